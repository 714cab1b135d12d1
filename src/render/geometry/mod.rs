//! Rays, surface points and the one place that creates secondary rays.
//!
//! Robustness follows pbrt-v4 (section 6.8): every intersection reports a conservative bound
//! on the floating-point error of its point, and [`spawn_ray`] / [`spawn_ray_to`] push the
//! origin just past that bound along the normal. In addition a spawned ray remembers the
//! primitive it leaves: all our primitives are convex (planar quads and triangles, spheres),
//! so a ray leaving one can only meet it again at the far side of a sphere. Together these
//! make self-intersection impossible without any scene-scale epsilon, which keeps images
//! invariant under scaling and translation.

mod accel;
mod degenerate;
mod flat;
mod lanes;
mod packet;
mod shapes;
mod triangle;
mod triangle_f64;

pub use accel::{Accel, PrimHit};
pub use shapes::{Primitive, Shape, Surface};

use glam::Vec3A;

use crate::render::math::{next_float_down, next_float_up};

/// Index of a primitive in [`Accel`]; `NO_PRIM` when there is none.
pub type PrimId = u32;
pub const NO_PRIM: PrimId = u32::MAX;

/// A ray with unit direction. Intersection ignores `target_prim` (a shadow ray's light) and
/// treats `origin_prim` as the convex primitive the ray leaves (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3A,
    pub d: Vec3A,
    pub t_max: f32,
    pub origin_prim: PrimId,
    pub target_prim: PrimId,
}

impl Ray {
    /// A primary ray (camera or light source origin not on any primitive).
    pub fn new(o: Vec3A, d: Vec3A) -> Ray {
        Ray {
            o,
            d,
            t_max: f32::INFINITY,
            origin_prim: NO_PRIM,
            target_prim: NO_PRIM,
        }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.o + self.d * t
    }
}

/// A point on a surface with the information needed to leave it robustly.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub p: Vec3A,
    /// Conservative absolute error bound of each component of `p`.
    pub p_error: Vec3A,
    /// Unit geometric normal as the shape defines it (outward for spheres and meshes,
    /// along cross(edge_u, edge_v) for quads).
    pub n: Vec3A,
    pub prim: PrimId,
}

/// The closest intersection of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    pub point: SurfacePoint,
}

/// Move `p` off its surface, to the side `w` points to, by just more than its error bound
/// (pbrt-v4 `OffsetRayOrigin`).
#[inline]
fn offset_origin(sp: &SurfacePoint, w: Vec3A) -> Vec3A {
    let d = sp.n.abs().dot(sp.p_error);
    let mut offset = sp.n * d;
    if w.dot(sp.n) < 0.0 {
        offset = -offset;
    }
    let mut po = sp.p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = next_float_up(po[i]);
        } else if offset[i] < 0.0 {
            po[i] = next_float_down(po[i]);
        }
    }
    po
}

/// A ray leaving a surface in unit direction `dir`: reflection, refraction, photon bounces,
/// final-gather rays. The only place such rays are made.
#[inline]
pub fn spawn_ray(from: &SurfacePoint, dir: Vec3A) -> Ray {
    Ray {
        o: offset_origin(from, dir),
        d: dir,
        t_max: f32::INFINITY,
        origin_prim: from.prim,
        target_prim: NO_PRIM,
    }
}

/// pbrt-v4's shadow epsilon: a shadow ray stops this fraction short of its target, so a
/// surface through the target itself (a light lying on a wall) does not occlude it.
const SHADOW_EPSILON: f32 = 1e-4;

/// A shadow ray from a surface to a point `to` (on a light, or a point light), skipping the
/// light's own primitive `to_prim`. Returns the ray and the unit direction and distance from
/// the surface point to the target.
#[inline]
pub fn spawn_ray_to(from: &SurfacePoint, to: Vec3A, to_prim: PrimId) -> Option<(Ray, Vec3A, f32)> {
    let delta = to - from.p;
    let dist = delta.length();
    if !(dist > 0.0) || !dist.is_finite() {
        return None;
    }
    let wi = delta / dist;
    let o = offset_origin(from, wi);
    let d = to - o;
    let len = d.length();
    if !(len > 0.0) {
        return None;
    }
    let ray = Ray {
        o,
        d: d / len,
        t_max: len * (1.0 - SHADOW_EPSILON),
        origin_prim: from.prim,
        target_prim: to_prim,
    };
    Some((ray, wi, dist))
}
