//! Precomputed irradiance (Christensen 1999): the global map read at the nearest of a
//! subset of its photons, whose estimates are made once per render.

use glam::Vec3A;
use rayon::prelude::*;

use super::estimate::{NORMAL_COS, Query, irradiance_knn_from};
use super::point_grid::PointGrid;
use super::{ClassMask, IRRADIANCE_STRIDE, KdItem, KnnScratch, Photon, PhotonMap};
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::math::Rgb;

/// A point with precomputed irradiance (a "radiance photon"). Kept small (16 bytes) so
/// that a search touches few cache lines: the irradiance itself lives in a separate array,
/// in the same order.
#[derive(Clone, Copy, Debug)]
struct IrradiancePoint {
    pos: [f32; 3],
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
/// The points are sorted into a uniform grid (`photon/point_grid/`): lookups come one per camera
/// vertex, each near the last one, and the last answer bounds the next search.
///
/// Built per render (it depends on k and on which path classes the integrator wants) from a
/// cached, camera-independent photon map.
pub struct IrradianceCache {
    /// None when there are no points.
    grid: Option<PointGrid<IrradiancePoint>>,
    /// Irradiance per path class of each point, in the grid's order.
    irradiance: Vec<[[f32; 3]; 3]>,
    r2_max: f32,
    /// Mean squared k-NN radius over the points (reported in the stats).
    pub mean_r2: f64,
}

/// The photons marked as irradiance points at tracing: their indices in `photons` and the
/// points, in that order. A pass over every photon of the map before the estimates can
/// start, so on all threads (measured: docs/performance-history.md, "irradiance points
/// picked in parallel").
fn pick_points(photons: &[Photon]) -> (Vec<usize>, Vec<IrradiancePoint>) {
    photons
        .par_iter()
        .enumerate()
        .filter(|(_, ph)| ph.is_irradiance_point())
        .map(|(i, ph)| {
            let point = IrradiancePoint {
                pos: ph.pos,
                n: ph.normal_i8(),
            };
            (i, point)
        })
        .unzip()
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
        let (picks, points) = pick_points(photons);
        let scale = IRRADIANCE_STRIDE as f32 / (IRRADIANCE_STRIDE - 1) as f32;
        let tracker = control.tracker(Phase::Precompute, picks.len() as u64);
        // Points per work item (the cancel grain): 1024 at k <= 16, fewer for larger k, as
        // a k-NN search costs about k (k goes to 100,000: 1024 of those are seconds).
        let chunk = (16 * 1024 / k.max(1)).clamp(1, 1024);
        // The grid depends on the points' positions only: it is sorted while the estimates
        // are made.
        let estimate = || {
            picks
                .par_chunks(chunk)
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
                            let est = irradiance_knn_from(map, &q, Some(i as u32), scratch);
                            (est.by_class.map(|c| (c * scale).to_array()), est.r2)
                        })
                        .collect();
                    tracker.advance(chunk.len() as u64);
                    Ok(out)
                })
                .collect::<Result<Vec<Vec<([[f32; 3]; 3], f32)>>, Cancelled>>()
        };
        let (parts, grid) = rayon::join(estimate, || PointGrid::build(&points, None));
        let parts = parts?;
        let mut irradiance = Vec::with_capacity(picks.len());
        let mut r2_sum = 0.0f64;
        for part in parts {
            for (e, r2) in part {
                r2_sum += r2 as f64;
                irradiance.push(e);
            }
        }
        let mean_r2 = if irradiance.is_empty() {
            0.0
        } else {
            r2_sum / points.len() as f64
        };
        let irradiance = grid.as_ref().map_or(Vec::new(), |g| {
            g.order().iter().map(|&i| irradiance[i as usize]).collect()
        });
        Ok(IrradianceCache {
            grid,
            irradiance,
            r2_max,
            mean_r2,
        })
    }

    /// Irradiance of `classes` at the nearest point on a surface facing like `n_side`; zero
    /// if none is within the search bound. `hint` carries the last answer between calls
    /// (neighbouring pixels mostly share their nearest point; see [`PointGrid::nearest`]).
    #[inline]
    pub fn lookup(
        &self,
        p: Vec3A,
        n_side: Vec3A,
        classes: ClassMask,
        hint: &mut Option<u32>,
    ) -> Rgb {
        let filter = |q: &IrradiancePoint| q.normal_dot(n_side) > NORMAL_COS;
        let Some((i, _)) = self
            .grid
            .as_ref()
            .and_then(|g| g.nearest(p, self.r2_max, &filter, *hint))
        else {
            return Rgb::ZERO;
        };
        *hint = Some(i);
        let by_class = &self.irradiance[i as usize];
        let mut e = Rgb::ZERO;
        for (c, v) in by_class.iter().enumerate() {
            if classes.0 & (1 << c) != 0 {
                e += Rgb::from_array(*v);
            }
        }
        e
    }

    pub fn len(&self) -> usize {
        self.grid.as_ref().map_or(0, PointGrid::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
