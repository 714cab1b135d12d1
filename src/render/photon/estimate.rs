//! Density estimation on photon maps.
//!
//! The radiance estimate (Jensen 2001, eq. 7.6): L_r(x, wo) ~ sum_p f_r(x, wp, wo) phi_p /
//! (pi r^2) over the k nearest photons (r: see `irradiance_knn` for the radius we use). Our
//! maps are read only through the Lambertian part of the BSDF (glossy and specular
//! reflection are ray traced), so it factors as (rho / pi) * E with the irradiance E = sum
//! phi_p / (pi r^2), which is what these functions return.
//!
//! Photons count only if they arrived on the query's side of the surface and lie on a
//! surface facing the same way (their stored normal within ~37 degrees of the query's): this
//! keeps light from leaking through thin two-sided walls and around corners.

use glam::Vec3A;

use super::occupancy::OccupancyGrid;
use super::point_grid::{BoxLimits, PointGrid};
use super::{ClassMask, KdItem, KnnScratch, Photon, PhotonMap};
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
    irradiance_knn_from(map, q, None, scratch)
}

/// [`irradiance_knn`]; with `at`, the query is at that photon of the map (the search then
/// starts from its leaf: [`super::KdTree::knn_at`]); `q.p` must be its position.
pub(super) fn irradiance_knn_from(
    map: &PhotonMap,
    q: &Query,
    at: Option<u32>,
    scratch: &mut KnnScratch,
) -> RadianceEstimate {
    let Query { p, k, r2_max, .. } = *q;
    debug_assert!(at.is_none_or(|i| map.tree.items()[i as usize].position() == p));
    let filter = query_filter(q);
    let r2 = match at {
        Some(at) => map.tree.knn_at(at, k + 1, r2_max, &filter, scratch),
        None => map.tree.knn(p, k + 1, r2_max, &filter, scratch),
    };
    estimate_from(map, scratch.found(), k, r2)
}

/// The photons a query counts: of its classes, on a surface facing its way, and not marked
/// if it skips those.
fn query_filter(q: &Query) -> impl Fn(&Photon) -> bool {
    let Query {
        n_side,
        classes,
        skip_marked,
        ..
    } = *q;
    move |ph: &Photon| {
        classes.contains(ph.class())
            && ph.normal().dot(n_side) > NORMAL_COS
            && !(skip_marked && ph.is_irradiance_point())
    }
}

/// The estimate from the k+1 nearest photons `found` (or fewer, all within the bound) and
/// the squared radius `r2` the search returned.
fn estimate_from(map: &PhotonMap, found: &[(f32, u32)], k: usize, r2: f32) -> RadianceEstimate {
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
    /// For small k, the map's photons (in tree order, so that ties break as in the tree) in
    /// cells of twice the search bound: a search's box then meets at most 8 cells, read
    /// directly (`PointGrid::knn`), where the kd-tree descends about 9 levels. Same answers.
    points: Option<PointGrid<Photon>>,
    pub k: usize,
    pub r2_max: f32,
}

/// The grid serves k-NN searches for k + 1 up to this (its sorted insertion suits few).
const GRID_MAX_K: usize = 8;

/// A search whose box meets more cells, or more photons, than this goes to the kd-tree:
/// with 64 photons a grid search reads about what the tree's branch and bound reads (its
/// descent and two or three leaves of 16). Without the photon limit, a dense caustic map
/// made the camera pass slower than the tree alone (measured: docs/performance-history.md,
/// "photon limit of grid searches").
const GRID_LIMITS: BoxLimits = BoxLimits {
    cells: 8,
    points: 64,
};

/// [`irradiance_knn`]'s answer for `q` (k + 1 at most GRID_MAX_K) from `grid`, the map's
/// photons in tree order, or None if the bound's box is beyond GRID_LIMITS.
fn grid_irradiance(
    map: &PhotonMap,
    grid: &PointGrid<Photon>,
    q: &Query,
    scratch: &mut KnnScratch,
) -> Option<RadianceEstimate> {
    let found = scratch.found_mut();
    let r2 = grid.knn(q.p, q.k + 1, q.r2_max, GRID_LIMITS, &query_filter(q), found)?;
    Some(estimate_from(map, found, q.k, r2))
}

impl<'a> CausticLookup<'a> {
    pub fn new(map: &'a PhotonMap, k: usize, r_max: f32) -> CausticLookup<'a> {
        // k + 1 <= GRID_MAX_K.
        let points = (k < GRID_MAX_K)
            .then(|| PointGrid::build(map.tree.items(), Some(2.0 * r_max)))
            .flatten();
        CausticLookup {
            map,
            grid: OccupancyGrid::build(map, r_max),
            points,
            k,
            r2_max: r_max * r_max,
        }
    }

    #[inline]
    pub fn irradiance(&self, p: Vec3A, n_side: Vec3A, scratch: &mut KnnScratch) -> Rgb {
        if self.grid.as_ref().is_some_and(|g| !g.maybe_occupied(p)) {
            return Rgb::ZERO;
        }
        let q = caustic_query(p, n_side, self.k, self.r2_max);
        let grid = self.points.as_ref();
        if let Some(est) = grid.and_then(|g| grid_irradiance(self.map, g, &q, scratch)) {
            return est.irradiance;
        }
        irradiance_knn(self.map, &q, scratch).irradiance
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
    irradiance_knn(map, &caustic_query(p, n_side, k, r2_max), scratch)
}

/// A query of a caustic map (all classes, none skipped).
fn caustic_query(p: Vec3A, n_side: Vec3A, k: usize, r2_max: f32) -> Query {
    Query {
        p,
        n_side,
        k,
        r2_max,
        classes: ClassMask::ALL,
        skip_marked: false,
    }
}
