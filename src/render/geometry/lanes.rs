//! The quad and sphere tests of tiny scenes in four SIMD lanes, written once for both ways
//! of filling the lanes: one ray against four primitives (`flat.rs`: the ray splatted) and
//! four rays against one primitive (`packet.rs`: the primitive splatted). Each lane does
//! the same operations in the same order whichever way, so the two agree bit for bit.
//!
//! Quads by their plane and two precomputed dot products, spheres by the discriminant of
//! Haines et al. (Ray Tracing Gems, chapter 7), as `shapes.rs` does one at a time.

use glam::{BVec4A, Vec3A, Vec4};

use super::{NO_PRIM, PrimId};

#[inline]
pub(super) fn dot3(a: &[Vec4; 3], b: [Vec4; 3]) -> Vec4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(super) fn splat3(v: Vec3A) -> [Vec4; 3] {
    [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)]
}

/// A ray's origin or target primitive as a float that matches no padding lane (-1).
#[inline]
pub(super) fn prim_f32(id: PrimId) -> f32 {
    if id == NO_PRIM { -2.0 } else { id as f32 }
}

/// Rays in four lanes: their origins, unit directions, and the primitives they leave and
/// aim at (as [`prim_f32`]).
pub(super) struct RayLanes {
    pub o: [Vec4; 3],
    pub d: [Vec4; 3],
    pub origin: Vec4,
    pub target: Vec4,
}

/// Quads in four lanes: ids as floats (exact below 2^24), corner, unit normal, the two
/// vectors whose dot products with (point - corner) give the quad's coordinates, and the
/// plane's offset n . corner.
#[derive(Clone, Copy)]
pub(super) struct QuadLanes {
    pub idf: Vec4,
    pub corner: [Vec4; 3],
    pub n: [Vec4; 3],
    pub su: [Vec4; 3],
    pub sv: [Vec4; 3],
    pub plane: Vec4,
}

/// Spheres in four lanes: ids as floats, centres and radii.
#[derive(Clone, Copy)]
pub(super) struct SphereLanes {
    pub idf: Vec4,
    pub center: [Vec4; 3],
    pub radius: Vec4,
}

/// Lane by lane, whether the ray meets the quad in (0, t_max), and where: (hit, t, s, v).
#[inline(always)]
pub(super) fn quad_hits(r: &RayLanes, q: &QuadLanes, t_max: Vec4) -> (BVec4A, Vec4, Vec4, Vec4) {
    let (o, d) = (&r.o, r.d);
    let denom = dot3(&q.n, d);
    let t = (q.plane - dot3(&q.n, *o)) / denom;
    let rel = [
        o[0] + t * d[0] - q.corner[0],
        o[1] + t * d[1] - q.corner[1],
        o[2] + t * d[2] - q.corner[2],
    ];
    let s = dot3(&q.su, rel);
    let v = dot3(&q.sv, rel);
    let (zero, one) = (Vec4::ZERO, Vec4::ONE);
    let hit = t.cmpgt(zero)
        & t.cmplt(t_max)
        & s.cmpge(zero)
        & s.cmple(one)
        & v.cmpge(zero)
        & v.cmple(one)
        & q.idf.cmpne(r.origin)
        & q.idf.cmpne(r.target);
    (hit, t, s, v)
}

/// Lane by lane, whether the ray meets the sphere in (0, t_max), and at which t; None when
/// no lane comes near it (most rays, for a small sphere).
#[inline(always)]
pub(super) fn sphere_hits(r: &RayLanes, sp: &SphereLanes, t_max: Vec4) -> Option<(BVec4A, Vec4)> {
    let (o, d) = (&r.o, r.d);
    let zero = Vec4::ZERO;
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
    // Leaving the sphere it starts on, or outside and moving away: no hit.
    let away = (from_me | c.cmpgt(zero)) & b.cmpge(zero);
    let candidate = !away & l2.cmple(r2) & disc.cmpge(zero);
    if !candidate.any() {
        return None;
    }
    let q = -b - disc.max(zero).sqrt().copysign(b);
    let a = c / q;
    let (t0, t1) = (a.min(q), a.max(q));
    let near_ok = t0.cmpgt(zero) & !from_me;
    let t = Vec4::select(near_ok, t0, t1);
    let hit = candidate & q.cmpne(zero) & t.cmpgt(zero) & t.cmplt(t_max) & sp.idf.cmpne(r.target);
    Some((hit, t))
}
