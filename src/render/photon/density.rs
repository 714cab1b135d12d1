//! How the camera pass reads a photon map: the three density estimators behind one type.
//!
//! - `photon`, caustic map: k nearest photons per query ([`CausticLookup`]).
//! - `photon`, global map: precomputed irradiance at the nearest point ([`IrradianceCache`]).
//! - `ppm`, both maps: a fixed radius per pass ([`RadiusLookup`]). Knaus and Zwicker (2011,
//!   "Progressive Photon Mapping: A Probabilistic Approach", ACM TOG 30(3), section 4) show
//!   that with a radius shrinking as r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1) over independent
//!   passes, both the variance and the expected error of the pass average vanish; the
//!   estimate must use the same radius everywhere in a pass, which a k-NN estimate does not.

use glam::Vec3A;

use super::estimate::NORMAL_COS;
use super::{CausticLookup, ClassMask, IrradianceCache, KnnScratch, Photon, PhotonMap, RangeGrid};
use crate::render::math::Rgb;

/// Per-thread scratch memory of the estimators.
#[derive(Default)]
pub struct DensityScratch {
    pub knn: KnnScratch,
    /// The last irradiance point found (a search hint; results do not depend on it).
    pub hint: Option<u32>,
}

/// A photon-map density estimator, as the camera pass uses it.
pub enum Density<'a> {
    Knn(CausticLookup<'a>),
    Cached(&'a IrradianceCache),
    Radius(RadiusLookup<'a>),
}

impl Density<'_> {
    /// Irradiance of the photons of `classes` at `p` on a surface facing `n_side`.
    #[inline]
    pub fn irradiance(
        &self,
        p: Vec3A,
        n_side: Vec3A,
        classes: ClassMask,
        scratch: &mut DensityScratch,
    ) -> Rgb {
        match self {
            // A caustic map holds caustic photons only: classes do not apply.
            Density::Knn(c) => c.irradiance(p, n_side, &mut scratch.knn),
            Density::Cached(c) => c.lookup(p, n_side, classes, &mut scratch.hint),
            Density::Radius(r) => r.irradiance(p, n_side, classes),
        }
    }

    /// The radius of a fixed-radius estimate (ppm's pass radius); None for an adaptive one.
    #[inline]
    pub fn fixed_radius(&self) -> Option<f32> {
        match self {
            Density::Radius(r) => Some(r.radius),
            Density::Knn(_) | Density::Cached(_) => None,
        }
    }
}

/// Fixed-radius irradiance: E = sum phi_p / (pi r^2) over the photons within r (of the
/// query's side and orientation, as in the k-NN estimate). The photons are searched in a
/// hashed grid built for the pass's radius (`range_grid.rs`); the tree only where no grid
/// could be built: an empty map, or a radius too large for f32 (every photon is within).
pub struct RadiusLookup<'a> {
    map: &'a PhotonMap,
    grid: Option<RangeGrid<Photon>>,
    radius: f32,
    r2: f32,
    /// unit / (pi r^2): a photon's relative power to irradiance.
    scale: f32,
}

impl<'a> RadiusLookup<'a> {
    pub fn new(map: &'a PhotonMap, radius: f32) -> RadiusLookup<'a> {
        let r2 = radius * radius;
        RadiusLookup {
            map,
            grid: RangeGrid::build(map.tree.items(), r2),
            radius,
            r2,
            scale: map.unit / (std::f32::consts::PI * r2),
        }
    }

    #[inline]
    pub fn irradiance(&self, p: Vec3A, n_side: Vec3A, classes: ClassMask) -> Rgb {
        if !(self.r2 > 0.0) {
            return Rgb::ZERO;
        }
        // The grid and the tree visit their photons in a fixed order, so this f32 sum is the
        // same on every run.
        let mut sum = Rgb::ZERO;
        let mut add = |ph: &Photon| {
            if classes.contains(ph.class()) && ph.normal().dot(n_side) > NORMAL_COS {
                sum += ph.relative_power();
            }
        };
        match &self.grid {
            Some(g) => g.within(p, &mut |ph, _| add(ph)),
            None => self.map.tree.within(p, self.r2, &mut |ph, _, _| add(ph)),
        }
        sum * self.scale
    }
}
