//! Four rays at once against a tiny scene's quads and spheres: the photon tracer's lanes
//! (`photon/trace.rs`). Where `flat.rs` tests one ray against four primitives a step, this
//! tests four rays against one primitive a step. A linear scan has no traversal, so four
//! unrelated rays (photon paths scatter every which way) share every step with none idle;
//! scene 1's five quads and two spheres take seven steps per four rays instead of three
//! steps (two of them with padding lanes) and a lane search per ray.
//!
//! Lane by lane the arithmetic is `flat.rs`'s, operation for operation, and primitives are
//! taken in the same order (quads, then spheres, by id) with the same strict test against
//! the closest hit so far, so every lane's answer is bit for bit the one-ray answer.

use glam::{Vec3A, Vec4};

use super::flat::{dot3, prim_f32, splat3};
use super::shapes::Shape;
use super::{PrimId, Ray};

/// Four rays, component by component. A lane without a ray never hits (t_max 0).
pub(super) struct Rays4 {
    o: [Vec4; 3],
    d: [Vec4; 3],
    t_max: Vec4,
    origin: Vec4,
    target: Vec4,
}

#[inline]
fn lanes3(v: [Vec3A; 4]) -> [Vec4; 3] {
    [0, 1, 2].map(|c| Vec4::new(v[0][c], v[1][c], v[2][c], v[3][c]))
}

impl Rays4 {
    #[inline]
    pub(super) fn new(rays: [Option<&Ray>; 4]) -> Rays4 {
        let idle = Ray {
            t_max: 0.0,
            ..Ray::new(Vec3A::ZERO, Vec3A::Z)
        };
        let r = rays.map(|r| *r.unwrap_or(&idle));
        Rays4 {
            o: lanes3(r.map(|r| r.o)),
            d: lanes3(r.map(|r| r.d)),
            t_max: Vec4::from_array(r.map(|r| r.t_max)),
            origin: Vec4::from_array(r.map(|r| prim_f32(r.origin_prim))),
            target: Vec4::from_array(r.map(|r| prim_f32(r.target_prim))),
        }
    }
}

/// Each lane's closest hit: primitive id as a float (-1: none), t (the ray's t_max if
/// none) and the quad coordinates (0 for spheres).
pub(super) struct Hits4 {
    pub idf: Vec4,
    pub t: Vec4,
    pub s: Vec4,
    pub v: Vec4,
}

/// One quad, every value in all four lanes.
struct QuadSplat {
    idf: Vec4,
    corner: [Vec4; 3],
    n: [Vec4; 3],
    su: [Vec4; 3],
    sv: [Vec4; 3],
    plane: Vec4,
}

/// One sphere, every value in all four lanes.
struct SphereSplat {
    idf: Vec4,
    center: [Vec4; 3],
    radius: Vec4,
}

/// A tiny scene's quads and spheres, splatted for `intersect4`.
pub(super) struct Splats {
    quads: Vec<QuadSplat>,
    spheres: Vec<SphereSplat>,
}

impl Splats {
    /// `prims` in id order; triangles are left to the caller.
    pub(super) fn new(prims: &[Shape]) -> Splats {
        let mut quads = Vec::new();
        let mut spheres = Vec::new();
        for (id, s) in prims.iter().enumerate() {
            let idf = Vec4::splat(id as f32);
            match *s {
                Shape::Quad {
                    corner,
                    n,
                    su,
                    sv,
                    plane,
                    ..
                } => quads.push(QuadSplat {
                    idf,
                    corner: splat3(corner),
                    n: splat3(n),
                    su: splat3(su),
                    sv: splat3(sv),
                    plane: Vec4::splat(plane),
                }),
                Shape::Sphere { center, radius } => spheres.push(SphereSplat {
                    idf,
                    center: splat3(center),
                    radius: Vec4::splat(radius),
                }),
                Shape::Triangle { .. } => {}
            }
        }
        Splats { quads, spheres }
    }

    /// Every lane's closest quad or sphere hit in (0, t_max). Of equal t, the first
    /// primitive in the order above, as in `Flat::intersect`.
    #[inline]
    pub(super) fn intersect4(&self, r: &Rays4) -> Hits4 {
        let (o, d) = (&r.o, r.d);
        let (zero, one) = (Vec4::ZERO, Vec4::ONE);
        let mut best = Hits4 {
            idf: Vec4::splat(-1.0),
            t: r.t_max,
            s: zero,
            v: zero,
        };
        for q in &self.quads {
            let denom = dot3(&q.n, d);
            let t = (q.plane - dot3(&q.n, *o)) / denom;
            let rel = [
                o[0] + t * d[0] - q.corner[0],
                o[1] + t * d[1] - q.corner[1],
                o[2] + t * d[2] - q.corner[2],
            ];
            let s = dot3(&q.su, rel);
            let v = dot3(&q.sv, rel);
            let hit = t.cmpgt(zero)
                & t.cmplt(best.t)
                & s.cmpge(zero)
                & s.cmple(one)
                & v.cmpge(zero)
                & v.cmple(one)
                & q.idf.cmpne(r.origin)
                & q.idf.cmpne(r.target);
            best.t = Vec4::select(hit, t, best.t);
            best.idf = Vec4::select(hit, q.idf, best.idf);
            best.s = Vec4::select(hit, s, best.s);
            best.v = Vec4::select(hit, v, best.v);
        }
        for sp in &self.spheres {
            let f = [
                o[0] - sp.center[0],
                o[1] - sp.center[1],
                o[2] - sp.center[2],
            ];
            let b = dot3(&f, d);
            let r2 = sp.radius * sp.radius;
            let c = dot3(&f, f) - r2;
            let from_me = sp.idf.cmpeq(r.origin);
            let perp = [f[0] - b * d[0], f[1] - b * d[1], f[2] - b * d[2]];
            let l2 = dot3(&perp, perp);
            let l = l2.max(zero).sqrt();
            let disc = (sp.radius - l) * (sp.radius + l);
            let away = (from_me | c.cmpgt(zero)) & b.cmpge(zero);
            let candidate = !away & l2.cmple(r2) & disc.cmpge(zero);
            if !candidate.any() {
                continue;
            }
            let q = -b - disc.max(zero).sqrt().copysign(b);
            let a = c / q;
            let (t0, t1) = (a.min(q), a.max(q));
            let near_ok = t0.cmpgt(zero) & !from_me;
            let t = Vec4::select(near_ok, t0, t1);
            let hit = candidate
                & q.cmpne(zero)
                & t.cmpgt(zero)
                & t.cmplt(best.t)
                & sp.idf.cmpne(r.target);
            best.t = Vec4::select(hit, t, best.t);
            best.idf = Vec4::select(hit, sp.idf, best.idf);
            best.s = Vec4::select(hit, zero, best.s);
            best.v = Vec4::select(hit, zero, best.v);
        }
        best
    }
}

/// The id of a lane's hit, if any.
#[inline]
pub(super) fn lane_prim(idf: f32) -> Option<PrimId> {
    (idf >= 0.0).then_some(idf as PrimId)
}
