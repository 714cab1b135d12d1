//! Four rays at once against a tiny scene's quads and spheres: the photon tracer's lanes
//! (`photon/trace.rs`). Where `flat.rs` tests one ray against four primitives a step, this
//! tests four rays against one primitive a step. A linear scan has no traversal, so four
//! unrelated rays (photon paths scatter every which way) share every step with none idle;
//! scene 1's five quads and two spheres take seven steps per four rays instead of three
//! steps (two of them with padding lanes) and a lane search per ray.
//!
//! Lane by lane the arithmetic is `flat.rs`'s (both call `lanes.rs`), and primitives are
//! taken in the same order (quads, then spheres, by id) with the same strict test against
//! the closest hit so far, so every lane's answer is bit for bit the one-ray answer.

use glam::{Vec3A, Vec4};

use super::lanes::{QuadLanes, RayLanes, SphereLanes, prim_f32, quad_hits, sphere_hits, splat3};
use super::shapes::Shape;
use super::{PrimId, Ray};

/// Four rays, component by component, and how far each may reach. A lane without a ray
/// never hits (t_max 0).
pub(super) struct Rays4 {
    lanes: RayLanes,
    t_max: Vec4,
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
            lanes: RayLanes {
                o: lanes3(r.map(|r| r.o)),
                d: lanes3(r.map(|r| r.d)),
                origin: Vec4::from_array(r.map(|r| prim_f32(r.origin_prim))),
                target: Vec4::from_array(r.map(|r| prim_f32(r.target_prim))),
            },
            t_max: Vec4::from_array(r.map(|r| r.t_max)),
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

/// A tiny scene's quads and spheres, each splatted over four lanes, for `intersect4`.
pub(super) struct Splats {
    quads: Vec<QuadLanes>,
    spheres: Vec<SphereLanes>,
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
                } => quads.push(QuadLanes {
                    idf,
                    corner: splat3(corner),
                    n: splat3(n),
                    su: splat3(su),
                    sv: splat3(sv),
                    plane: Vec4::splat(plane),
                }),
                Shape::Sphere { center, radius } => spheres.push(SphereLanes {
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
        let zero = Vec4::ZERO;
        let mut best = Hits4 {
            idf: Vec4::splat(-1.0),
            t: r.t_max,
            s: zero,
            v: zero,
        };
        for q in &self.quads {
            let (hit, t, s, v) = quad_hits(&r.lanes, q, best.t);
            best.t = Vec4::select(hit, t, best.t);
            best.idf = Vec4::select(hit, q.idf, best.idf);
            best.s = Vec4::select(hit, s, best.s);
            best.v = Vec4::select(hit, v, best.v);
        }
        for sp in &self.spheres {
            let Some((hit, t)) = sphere_hits(&r.lanes, sp, best.t) else {
                continue;
            };
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
