//! Photon maps (Jensen 1996, "Global Illumination using Photon Maps"): photons traced from
//! the lights are stored where they land on non-specular surfaces, in a global map and a
//! caustic map (paths light -> specular+ -> diffuse), and read back by density estimation.
//!
//! [`PhotonMaps`] is an immutable value that does not depend on the camera: the server
//! caches it and renders many views from one.

mod cells;
mod density;
mod estimate;
mod irradiance;
mod kdtree;
mod occupancy;
mod path;
mod point_grid;
mod range_grid;
mod targets;
#[cfg(test)]
mod test_points;
mod trace;

pub use density::{Density, DensityScratch, RadiusLookup};
pub use estimate::{CausticLookup, Query, RadianceEstimate, caustic_irradiance, irradiance_knn};
pub use irradiance::IrradianceCache;
pub use kdtree::{KdItem, KdTree, KnnScratch};
pub use occupancy::OccupancyGrid;
pub use range_grid::RangeGrid;
pub use targets::{CausticTargets, TargetedDirection};
pub use trace::{PhotonParams, PhotonStore, TraceOutput, build_photon_maps};

use glam::Vec3A;

use crate::render::control::{Cancelled, Control};
use crate::render::math::{Rgb, round_to_i32};

/// How a photon reached the surface it is stored on; estimates pick classes so that no
/// light path is counted twice (see `integrator`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum PathClass {
    /// First hit after leaving the light: direct illumination (L D).
    Direct = 0,
    /// Only specular bounces before: a caustic (L S+ D).
    Caustic = 1,
    /// At least one non-specular bounce before (L .* D .* D).
    Indirect = 2,
}

/// A set of path classes, as bits (1 << class).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassMask(pub u8);

impl ClassMask {
    pub const NONE: ClassMask = ClassMask(0);
    pub const ALL: ClassMask = ClassMask(0b111);

    pub const fn of(classes: &[PathClass]) -> ClassMask {
        let mut bits = 0;
        let mut i = 0;
        while i < classes.len() {
            bits |= 1 << classes[i] as u8;
            i += 1;
        }
        ClassMask(bits)
    }

    #[inline]
    pub fn contains(self, class: PathClass) -> bool {
        self.0 & (1 << class as u8) != 0
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// A stored photon: 28 bytes (position 12, flux 12, normal 3, flags 1).
///
/// Flux is stored relative to the map's `unit` (the flux a photon carries when it leaves a
/// light), so it is O(1) whatever the light's power or the photon count. There is no
/// incoming direction: the maps are only ever read through the Lambertian part of a BSDF
/// (glossy and specular reflection are ray traced), which does not depend on it. (A 24-byte
/// layout with f16 flux and a 16-bit direction was slower: its conversions slowed photon
/// tracing and every estimate; measured: docs/performance-history.md, "24-byte photons".)
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Photon {
    pub pos: [f32; 3],
    power: [f32; 3],
    /// Surface normal on the side the photon arrived from, as i8 components of length 127:
    /// the side test of every candidate photon is then three multiply-adds.
    n: [i8; 3],
    /// Bits 0-1: PathClass; bit 2: irradiance point.
    flags: u8,
}

const _: () = assert!(std::mem::size_of::<Photon>() == 28);

/// One photon path in IRRADIANCE_STRIDE is marked to carry precomputed irradiance (see
/// [`IrradianceCache`]).
pub const IRRADIANCE_STRIDE: u64 = 4;

const IRRADIANCE_POINT: u8 = 1 << 2;

impl Photon {
    /// `relative_power`: flux in units of the map's `unit`.
    pub fn new(
        pos: Vec3A,
        relative_power: Rgb,
        n_side: Vec3A,
        class: PathClass,
        irradiance_point: bool,
    ) -> Photon {
        Photon {
            pos: pos.to_array(),
            power: relative_power.to_array(),
            n: n_side.to_array().map(|c| round_to_i32(c * 127.0) as i8),
            flags: class as u8
                | if irradiance_point {
                    IRRADIANCE_POINT
                } else {
                    0
                },
        }
    }

    /// Whether this photon's path was picked to carry precomputed irradiance.
    #[inline]
    pub fn is_irradiance_point(&self) -> bool {
        self.flags & IRRADIANCE_POINT != 0
    }

    /// Flux in units of the map's `unit` (see [`PhotonMap::power`]).
    #[inline]
    pub fn relative_power(&self) -> Rgb {
        Rgb::from_array(self.power)
    }

    /// The stored normal's i8 components (length 127).
    #[inline]
    pub fn normal_i8(&self) -> [i8; 3] {
        self.n
    }

    /// The (approximately unit) surface normal.
    #[inline]
    pub fn normal(&self) -> Vec3A {
        Vec3A::new(self.n[0] as f32, self.n[1] as f32, self.n[2] as f32) * (1.0 / 127.0)
    }

    #[inline]
    pub fn class(&self) -> PathClass {
        match self.flags & 3 {
            0 => PathClass::Direct,
            1 => PathClass::Caustic,
            _ => PathClass::Indirect,
        }
    }
}

impl KdItem for Photon {
    #[inline]
    fn position(&self) -> Vec3A {
        Vec3A::from_array(self.pos)
    }

    #[inline]
    fn coord(&self, axis: usize) -> f32 {
        self.pos[axis]
    }
}

/// One photon map: photons in a balanced kd-tree, the number emitted to make them, and the
/// flux unit their stored powers are relative to (watts, luminance of a photon at emission:
/// total light power / emitted).
pub struct PhotonMap {
    pub tree: KdTree<Photon>,
    pub emitted: u64,
    pub unit: f32,
}

impl PhotonMap {
    pub fn new(photons: Vec<Photon>, emitted: u64, unit: f32) -> PhotonMap {
        PhotonMap {
            tree: KdTree::build(photons),
            emitted,
            unit,
        }
    }

    /// [`PhotonMap::new`], giving up if `control` is cancelled while the tree is balanced.
    pub fn build(
        photons: Vec<Photon>,
        emitted: u64,
        unit: f32,
        control: &Control,
    ) -> Result<PhotonMap, Cancelled> {
        let tree =
            KdTree::build_cancellable(photons, &|| control.check().is_err()).ok_or(Cancelled)?;
        Ok(PhotonMap {
            tree,
            emitted,
            unit,
        })
    }

    /// A photon's flux in watts.
    #[inline]
    pub fn power(&self, photon: &Photon) -> Rgb {
        photon.relative_power() * self.unit
    }

    pub fn len(&self) -> usize {
        self.tree.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }

    /// Memory held by the photons and the tree's splits.
    pub fn bytes(&self) -> usize {
        self.tree.len() * std::mem::size_of::<Photon>() + self.tree.overhead_bytes()
    }

    /// Total stored flux, by compensated f64 summation: no precision lost whatever the
    /// number of photons ([`sum_power`]).
    pub fn total_power(&self) -> [f64; 3] {
        sum_power(self.tree.items().iter().map(Photon::relative_power))
            .map(|s| s * self.unit as f64)
    }
}

/// The sum of many photons' powers, exact to f64's last bits (Neumaier summation).
pub fn sum_power(powers: impl Iterator<Item = Rgb>) -> [f64; 3] {
    let mut sum = crate::render::math::CompensatedSum::default();
    powers.for_each(|p| sum.add(p));
    sum.total()
}

/// The photon maps of one (scene, photon parameters) pair, and how they were made.
pub struct PhotonMaps {
    pub global: Option<PhotonMap>,
    pub caustic: Option<PhotonMap>,
    pub params: PhotonParams,
    /// Seconds spent tracing photons and building the trees.
    pub trace_seconds: f64,
    pub build_seconds: f64,
}

impl PhotonMaps {
    /// No maps (for a render that traced none), for `params`.
    pub fn none(params: PhotonParams) -> PhotonMaps {
        PhotonMaps {
            global: None,
            caustic: None,
            params,
            trace_seconds: 0.0,
            build_seconds: 0.0,
        }
    }

    pub fn bytes(&self) -> usize {
        self.global.as_ref().map_or(0, |m| m.bytes())
            + self.caustic.as_ref().map_or(0, |m| m.bytes())
    }
}
