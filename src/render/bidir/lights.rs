//! The lights as bidirectional sampling needs them: every way a light point can be
//! sampled, with its density, so that the weights of the techniques that could have made a
//! path can be compared (Veach 1997, chapter 10; Georgiev et al. 2012, technical report,
//! section 5). Densities here leave out the light-selection probability, which the caller
//! multiplies in.
//!
//! - emission (light subpaths): a point by area (a point light's position), a direction
//!   cosine-weighted about an area light's normal (uniform for a point light);
//! - direct sampling (next-event estimation from a receiver): a point light exactly, a quad by
//!   area, a sphere uniformly over the cone it subtends from the receiver (`Light::sample_li`);
//! - hits: a camera path reaching an area light's surface.

use std::f32::consts::{FRAC_1_PI, PI};

use glam::{Vec2, Vec3A};

use crate::render::geometry::{PrimId, Ray};
use crate::render::light::Light;
use crate::render::math::Rgb;

/// A light subpath's first vertex and ray.
pub(super) struct Emitted {
    pub ray: Ray,
    /// The point left and its normal (zero for a point light).
    pub p: Vec3A,
    pub n: Vec3A,
    /// Emitted radiance times the cosine at the light, over the density of having emitted
    /// it (point and direction): the subpath's starting throughput, before selection.
    pub weight: Rgb,
    /// Density of the point (area) times the direction (solid angle).
    pub emission_pdf: f32,
    /// The cosine of the emitted direction at the light (1 for a point light).
    pub cos_light: f32,
    /// A point light: no other technique can reach its position.
    pub delta: bool,
}

/// A direct sample of a light from a receiving point.
pub(super) struct Direct {
    pub wi: Vec3A,
    pub target: Vec3A,
    pub prim: PrimId,
    /// Radiance arriving along `wi` (a point light: its intensity).
    pub radiance: Rgb,
    /// Solid-angle density of the direction from the receiver (a point light:
    /// distance^2, its area density 1 converted).
    pub direct_pdf: f32,
    /// Density of emitting the sampled point toward the receiver (point times direction).
    pub emission_pdf: f32,
    pub cos_light: f32,
    pub delta: bool,
}

impl Light {
    /// Area density of the point an area light emits from (its uniform area sampling).
    fn position_pdf(&self) -> f32 {
        match *self {
            Light::Point { .. } => 1.0,
            Light::Sphere { radius, .. } => 1.0 / (4.0 * PI * radius * radius),
            Light::Quad { area, .. } => 1.0 / area,
        }
    }

    /// Emit a light subpath.
    pub(super) fn emit(&self, u_pos: Vec2, u_dir: Vec2) -> Option<Emitted> {
        let e = self.sample_emission(u_pos, u_dir);
        let origin = self.emission_origin(u_pos);
        let dir = e.ray.d;
        let (n, cos_light, delta) = match origin.normal {
            None => (Vec3A::ZERO, 1.0, true),
            Some(n) => (n, n.dot(dir), false),
        };
        let emission_pdf = self.position_pdf() * origin.direction_pdf(dir);
        if !(emission_pdf > 0.0) || !(cos_light > 0.0) {
            return None;
        }
        Some(Emitted {
            ray: e.ray,
            p: origin.sp.p,
            n,
            // Radiance cos / (point pdf * cos / pi) is the light's power per unit selection.
            weight: e.flux,
            emission_pdf,
            cos_light,
            delta,
        })
    }

    /// The area density with which direct sampling from `receiver` picks the light point
    /// `p` (normal `n`): a quad's uniform area density, a sphere's cone density converted
    /// to area; 1 for a point light (a delta).
    pub(super) fn direct_pdf_area(&self, p: Vec3A, n: Vec3A, receiver: Vec3A) -> f32 {
        match *self {
            Light::Point { .. } => 1.0,
            Light::Quad { area, .. } => 1.0 / area,
            Light::Sphere { center, radius, .. } => {
                let d = receiver - p;
                let dist2 = d.length_squared();
                let cos = n.dot(d).abs() / dist2.sqrt();
                cone_pdf(center, radius, receiver) * cos / dist2
            }
        }
    }

    /// Density of emitting from `p` (normal `n`) toward direction `dir`.
    pub(super) fn emission_pdf(&self, n: Vec3A, dir: Vec3A) -> f32 {
        match *self {
            Light::Point { .. } => 0.25 * FRAC_1_PI,
            _ => self.position_pdf() * n.dot(dir).max(0.0) * FRAC_1_PI,
        }
    }

    /// Sample the light directly from `receiver` (next-event estimation).
    pub(super) fn direct(&self, receiver: Vec3A, u: Vec2) -> Option<Direct> {
        let ls = self.sample_li(receiver, u)?;
        let d = ls.target - receiver;
        let dist2 = d.length_squared();
        let (n, radiance, direct_pdf) = match *self {
            // A delta in area measure (density 1) is distance^2 in solid angle, the
            // intensity the "radiance" that density divides (SmallVCM's point light).
            Light::Point { power, .. } => (Vec3A::ZERO, power / (4.0 * PI), dist2),
            Light::Quad {
                n, area, radiance, ..
            } => (n, radiance, dist2 / ((-n).dot(ls.wi) * area)),
            Light::Sphere {
                center,
                radius,
                radiance,
                ..
            } => {
                let n = (ls.target - center).normalize();
                (n, radiance, cone_pdf(center, radius, receiver))
            }
        };
        let cos_light = match *self {
            Light::Point { .. } => 1.0,
            _ => n.dot(-ls.wi),
        };
        if !(direct_pdf > 0.0 && direct_pdf.is_finite() && cos_light > 0.0) {
            return None;
        }
        Some(Direct {
            wi: ls.wi,
            target: ls.target,
            prim: ls.prim,
            radiance,
            direct_pdf,
            emission_pdf: self.emission_pdf(n, -ls.wi),
            cos_light,
            delta: self.is_delta(),
        })
    }
}

/// Solid-angle density of sampling a sphere uniformly over the cone it subtends from `p`.
fn cone_pdf(center: Vec3A, radius: f32, p: Vec3A) -> f32 {
    let dc2 = (center - p).length_squared();
    let r2 = radius * radius;
    if dc2 <= r2 {
        return 0.0;
    }
    let sin2_max = r2 / dc2;
    let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
    let one_minus_cos_max = sin2_max / (1.0 + cos_max);
    1.0 / (2.0 * PI * one_minus_cos_max)
}
