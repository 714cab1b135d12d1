//! Density estimation on photon maps.
//!
//! The radiance estimate (Jensen 2001, eq. 7.6): L_r(x, wo) ~ sum_p f_r(x, wp, wo) phi_p /
//! (pi r^2) over the k nearest photons (r: see `irradiance_knn` for the radius we use). Our maps are read only
//! through the Lambertian part of the BSDF (glossy and specular reflection are ray traced),
//! so it factors as (rho / pi) * E with the irradiance E = sum phi_p / (pi r^2), which is what
//! these functions return.
//!
//! Photons count only if they arrived on the query's side of the surface and lie on a
//! surface facing the same way (their stored normal within ~37 degrees of the query's): this
//! keeps light from leaking through thin two-sided walls and around corners.

use glam::Vec3A;
use rayon::prelude::*;

use super::occupancy::OccupancyGrid;
use super::{ClassMask, IRRADIANCE_STRIDE, KdItem, KdTree, KnnScratch, PhotonMap};
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::math::Rgb;

/// Minimum cosine between a photon's surface normal and the query's.
pub(super) const NORMAL_COS: f32 = 0.8;

/// Fixed-point scale for order-independent sums of relative photon powers (which are O(1);
/// 2^32 leaves room for 10^8 photons of power 10 in an i64).
const FIXED_ONE: f32 = 4_294_967_296.0;

/// An irradiance estimate and the search that made it.
#[derive(Clone, Copy, Debug, Default)]
pub struct RadianceEstimate {
    pub irradiance: Rgb,
    /// The same estimate split by path class (indexed by `PathClass as usize`).
    pub by_class: [Rgb; 3],
    /// Squared radius of the disc the photons were gathered from.
    pub r2: f32,
}

/// An irradiance query: at `p` on a surface facing `n_side`, from the k nearest photons of
/// `classes` within sqrt(r2_max); with `skip_marked`, photons marked as irradiance points are
/// left out (see [`IrradianceCache`]).
#[derive(Clone, Copy, Debug)]
pub struct Query {
    pub p: Vec3A,
    pub n_side: Vec3A,
    pub k: usize,
    pub r2_max: f32,
    pub classes: ClassMask,
    pub skip_marked: bool,
}

/// Irradiance for a [`Query`].
///
/// The estimate is sum of the k nearest / (pi r_{k+1}^2), r_{k+1} the distance to the next
/// photon: for photons scattered as a Poisson process this is unbiased, whereas Jensen's
/// k / (pi r_k^2) overestimates by k/(k-1) (+2% at k = 50, and no finite mean at k = 1); it
/// is the (k-1)/(n V_k) form of the nearest-neighbour density estimate (Loftsgaarden and
/// Quesenberry 1965) with k+1 neighbours. If fewer than k+1 photons lie within the bound, all
/// of them are summed over the bound's disc, which is unbiased too.
pub fn irradiance_knn(map: &PhotonMap, q: &Query, scratch: &mut KnnScratch) -> RadianceEstimate {
    let Query {
        p,
        n_side,
        k,
        r2_max,
        classes,
        skip_marked,
    } = *q;
    let filter = |ph: &super::Photon| {
        classes.contains(ph.class())
            && ph.normal().dot(n_side) > NORMAL_COS
            && !(skip_marked && ph.is_irradiance_point())
    };
    let r2 = map.tree.knn(p, k + 1, r2_max, &filter, scratch);
    let found = scratch.found();
    // With k+1 found the farthest (the last) only sets the radius.
    let inner = if found.len() == k + 1 {
        &found[..k]
    } else {
        found
    };
    if inner.is_empty() || !(r2 > 0.0) {
        return RadianceEstimate {
            r2,
            ..Default::default()
        };
    }
    // Summed in 32.32 fixed point: integer addition is associative, so the result does not
    // depend on the order the search found the photons in (which depends on the thread's
    // radius guess), and images stay bit-identical across thread counts.
    let items = map.tree.items();
    let mut sums = [[0i64; 3]; 3];
    for &(_, i) in inner {
        let ph = &items[i as usize];
        let sum = &mut sums[ph.class() as usize];
        for (acc, c) in sum.iter_mut().zip(ph.relative_power().to_array()) {
            // Saturating: a valid scene keeps powers O(1), but nothing here may overflow.
            *acc = acc.saturating_add((c * FIXED_ONE) as i64);
        }
    }
    let scale = map.unit as f64 / (FIXED_ONE as f64 * std::f64::consts::PI * r2 as f64);
    let by_class = sums.map(|c| Rgb::from_array(c.map(|x| (x as f64 * scale) as f32)));
    RadianceEstimate {
        irradiance: by_class[0] + by_class[1] + by_class[2],
        by_class,
        r2,
    }
}

/// Per-pixel irradiance estimates from a caustic map (Jensen: caustics are estimated at
/// every camera path vertex, for sharpness). An occupancy grid skips the search wherever no
/// caustic photon lies within reach, which is most of a scene.
pub struct CausticLookup<'a> {
    pub map: &'a PhotonMap,
    grid: Option<OccupancyGrid>,
    pub k: usize,
    pub r2_max: f32,
}

impl<'a> CausticLookup<'a> {
    pub fn new(map: &'a PhotonMap, k: usize, r_max: f32) -> CausticLookup<'a> {
        CausticLookup {
            map,
            grid: OccupancyGrid::build(map, r_max),
            k,
            r2_max: r_max * r_max,
        }
    }

    #[inline]
    pub fn irradiance(&self, p: Vec3A, n_side: Vec3A, scratch: &mut KnnScratch) -> Rgb {
        if self.grid.as_ref().is_some_and(|g| !g.maybe_occupied(p)) {
            return Rgb::ZERO;
        }
        caustic_irradiance(self.map, p, n_side, self.k, self.r2_max, scratch).irradiance
    }
}

/// Irradiance from the caustic map (it holds caustic photons only).
pub fn caustic_irradiance(
    map: &PhotonMap,
    p: Vec3A,
    n_side: Vec3A,
    k: usize,
    r2_max: f32,
    scratch: &mut KnnScratch,
) -> RadianceEstimate {
    let q = Query {
        p,
        n_side,
        k,
        r2_max,
        classes: ClassMask::ALL,
        skip_marked: false,
    };
    irradiance_knn(map, &q, scratch)
}

/// A point with precomputed irradiance (a "radiance photon").
#[derive(Clone, Copy, Debug)]
/// Kept small (20 bytes) so that a search touches few cache lines: the irradiance itself
/// lives in a separate array at `index`.
struct IrradiancePoint {
    pos: [f32; 3],
    index: u32,
    /// Surface normal as i8 components of length 127 (as in [`super::Photon`]).
    n: [i8; 3],
}

impl IrradiancePoint {
    #[inline]
    fn normal_dot(&self, v: Vec3A) -> f32 {
        (self.n[0] as f32 * v.x + self.n[1] as f32 * v.y + self.n[2] as f32 * v.z) * (1.0 / 127.0)
    }
}

impl KdItem for IrradiancePoint {
    #[inline]
    fn position(&self) -> Vec3A {
        Vec3A::from_array(self.pos)
    }
}

/// Irradiance precomputed at a subset of the photons (Christensen 1999, "Faster Photon Map
/// Global Illumination", JGT 4(3)): the k-NN estimate is paid once per point instead of once
/// per pixel or gather ray, and a lookup is a single nearest-point search.
///
/// Unlike Christensen's every-fourth photon, the points are the photons of one path in
/// IRRADIANCE_STRIDE chosen by a hash of the path index (marked at tracing), and their
/// estimates use only the other photons, scaled by stride / (stride - 1). A lookup returns
/// the estimate of the nearest point, so points are found in proportion to the area of their
/// Voronoi cells; if a point's estimate used the photons around it, sparse neighbourhoods
/// (large cells, low estimates) would be over-represented (we measured -2.5% on a lit
/// floor). With an independent thinning the estimates do not depend on the cells.
///
/// Built per render (it depends on k and on which path classes the integrator wants) from a
/// cached, camera-independent photon map.
pub struct IrradianceCache {
    tree: KdTree<IrradiancePoint>,
    /// Irradiance per path class of each point, by `IrradiancePoint::index`.
    irradiance: Vec<[[f32; 3]; 3]>,
    r2_max: f32,
    /// Mean squared k-NN radius over the points (reported in the stats).
    pub mean_r2: f64,
}

impl IrradianceCache {
    pub fn build(
        map: &PhotonMap,
        k: usize,
        r2_max: f32,
        classes: ClassMask,
        control: &Control,
    ) -> Result<IrradianceCache, Cancelled> {
        let photons = map.tree.items();
        let picks: Vec<usize> = (0..photons.len())
            .filter(|&i| photons[i].is_irradiance_point())
            .collect();
        let scale = IRRADIANCE_STRIDE as f32 / (IRRADIANCE_STRIDE - 1) as f32;
        let tracker = control.tracker(Phase::Precompute, picks.len() as u64);
        const CHUNK: usize = 1024;
        let parts: Vec<Vec<([[f32; 3]; 3], f32)>> = picks
            .par_chunks(CHUNK)
            .map_init(KnnScratch::default, |scratch, chunk| {
                control.check()?;
                let out = chunk
                    .iter()
                    .map(|&i| {
                        let ph = &photons[i];
                        let q = Query {
                            p: ph.position(),
                            n_side: ph.normal(),
                            k,
                            r2_max,
                            classes,
                            skip_marked: true,
                        };
                        let est = irradiance_knn(map, &q, scratch);
                        (est.by_class.map(|c| (c * scale).to_array()), est.r2)
                    })
                    .collect();
                tracker.advance(chunk.len() as u64);
                Ok(out)
            })
            .collect::<Result<_, Cancelled>>()?;
        let mut irradiance = Vec::with_capacity(picks.len());
        let mut r2_sum = 0.0f64;
        for part in parts {
            for (e, r2) in part {
                r2_sum += r2 as f64;
                irradiance.push(e);
            }
        }
        let points: Vec<IrradiancePoint> = picks
            .iter()
            .enumerate()
            .map(|(index, &i)| IrradiancePoint {
                pos: photons[i].pos,
                index: index as u32,
                n: photons[i].normal_i8(),
            })
            .collect();
        let mean_r2 = if irradiance.is_empty() {
            0.0
        } else {
            r2_sum / points.len() as f64
        };
        Ok(IrradianceCache {
            tree: KdTree::build(points),
            irradiance,
            r2_max,
            mean_r2,
        })
    }

    /// Irradiance of `classes` at the nearest point on a surface facing like `n_side`; zero
    /// if none is within the search bound. `hint` carries the last answer between calls
    /// (neighbouring pixels mostly share their nearest point; see [`KdTree::nearest`]).
    #[inline]
    pub fn lookup(
        &self,
        p: Vec3A,
        n_side: Vec3A,
        classes: ClassMask,
        hint: &mut Option<u32>,
    ) -> Rgb {
        let filter = |q: &IrradiancePoint| q.normal_dot(n_side) > NORMAL_COS;
        let Some((i, _)) = self.tree.nearest(p, self.r2_max, &filter, *hint) else {
            return Rgb::ZERO;
        };
        *hint = Some(i);
        let by_class = &self.irradiance[self.tree.items()[i as usize].index as usize];
        let mut e = Rgb::ZERO;
        for (c, v) in by_class.iter().enumerate() {
            if classes.0 & (1 << c) != 0 {
                e += Rgb::from_array(*v);
            }
        }
        e
    }

    pub fn len(&self) -> usize {
        self.tree.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }
}
