//! Intersection for tiny scenes (the seed's boxes of a few quads and spheres): no BVH, the
//! primitives tested four at a time in structure-of-arrays form. A BVH over a handful of
//! large primitives culls almost nothing; testing all of them in SIMD lanes takes fewer
//! instructions than one by one (measured: docs/performance-history.md, "flat SIMD tests").
//!
//! Same arithmetic as `shapes.rs`, lane by lane (the tests themselves are in `lanes.rs`,
//! shared with `packet.rs`). Padding lanes never hit.

use glam::{Vec3A, Vec4};

use super::lanes::{QuadLanes, RayLanes, SphereLanes, prim_f32, quad_hits, sphere_hits, splat3};
use super::packet::{Rays4, Splats, lane_prim};
use super::shapes::{Shape, ShapeHit};
use super::{NO_PRIM, PrimId, Ray};

/// Four quads, component by component (padding lanes: id -1, zero normal).
#[derive(Clone, Copy)]
struct Quads4 {
    id: [PrimId; 4],
    lanes: QuadLanes,
}

/// Four spheres, component by component (padding lanes: id -1, radius 0).
#[derive(Clone, Copy)]
struct Spheres4 {
    id: [PrimId; 4],
    lanes: SphereLanes,
}

pub struct Flat {
    quads: Vec<Quads4>,
    spheres: Vec<Spheres4>,
    /// Anything else (triangles), tested one by one.
    others: Vec<(PrimId, Shape)>,
    /// The quads and spheres again, for four rays at a time.
    splats: Splats,
}

fn lanes<const N: usize>(v: [Vec3A; N]) -> [Vec4; 3] {
    let c = |i: usize| {
        let mut a = [0.0f32; 4];
        for (l, x) in v.iter().enumerate().take(4) {
            a[l] = x[i];
        }
        Vec4::from_array(a)
    };
    [c(0), c(1), c(2)]
}

/// Lane ids as floats; padding lanes are -1.
fn ids_f32(id: &[PrimId; 4]) -> Vec4 {
    Vec4::from_array(id.map(|i| if i == NO_PRIM { -1.0 } else { i as f32 }))
}

impl Quads4 {
    /// Up to four quads in lanes, the rest padding.
    fn pack(ch: &[(PrimId, Shape)]) -> Quads4 {
        let mut id = [NO_PRIM; 4];
        // Padding: a plane with zero normal never yields a finite positive t.
        let (mut corner, mut n, mut su, mut sv) = (
            [Vec3A::ZERO; 4],
            [Vec3A::ZERO; 4],
            [Vec3A::ZERO; 4],
            [Vec3A::ZERO; 4],
        );
        let mut plane = [0.0f32; 4];
        for (l, (pid, s)) in ch.iter().enumerate() {
            if let Shape::Quad {
                corner: c,
                n: nn,
                su: a,
                sv: b,
                plane: p,
                ..
            } = *s
            {
                id[l] = *pid;
                (corner[l], n[l], su[l], sv[l], plane[l]) = (c, nn, a, b, p);
            }
        }
        Quads4 {
            id,
            lanes: QuadLanes {
                idf: ids_f32(&id),
                corner: lanes(corner),
                n: lanes(n),
                su: lanes(su),
                sv: lanes(sv),
                plane: Vec4::from_array(plane),
            },
        }
    }
}

impl Spheres4 {
    /// Up to four spheres in lanes, the rest padding.
    fn pack(ch: &[(PrimId, Shape)]) -> Spheres4 {
        let mut id = [NO_PRIM; 4];
        let mut center = [Vec3A::ZERO; 4];
        // Padding: radius 0 is never hit (the discriminant test is strict).
        let mut radius = [0.0f32; 4];
        for (l, (pid, s)) in ch.iter().enumerate() {
            if let Shape::Sphere {
                center: c,
                radius: r,
            } = *s
            {
                id[l] = *pid;
                center[l] = c;
                radius[l] = r;
            }
        }
        Spheres4 {
            id,
            lanes: SphereLanes {
                idf: ids_f32(&id),
                center: lanes(center),
                radius: Vec4::from_array(radius),
            },
        }
    }
}

impl Flat {
    /// `prims` in id order.
    pub fn new(prims: &[Shape]) -> Flat {
        let mut quads = Vec::new();
        let mut spheres = Vec::new();
        let mut others = Vec::new();
        for (id, s) in prims.iter().enumerate() {
            match *s {
                Shape::Quad { .. } => quads.push((id as PrimId, *s)),
                Shape::Sphere { .. } => spheres.push((id as PrimId, *s)),
                Shape::Triangle { .. } => others.push((id as PrimId, *s)),
            }
        }
        Flat {
            quads: quads.chunks(4).map(Quads4::pack).collect(),
            spheres: spheres.chunks(4).map(Spheres4::pack).collect(),
            others,
            splats: Splats::new(prims),
        }
    }

    /// The closest hit in (0, ray.t_max): its primitive and shape hit. Of equal t, quads
    /// win over spheres over others, and lower lanes over higher.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<(PrimId, ShapeHit)> {
        self.search::<false>(ray)
    }

    /// Whether anything is hit in (0, ray.t_max): shadow rays stop at the first group of
    /// four with a hit.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.search::<true>(ray).is_some()
    }

    /// [`Flat::intersect`] for four rays (None: an idle lane, which gets None), each lane's
    /// answer bit for bit the one-ray answer (see `packet.rs`).
    #[inline]
    pub fn intersect4(&self, rays: [Option<&Ray>; 4]) -> [Option<(PrimId, ShapeHit)>; 4] {
        let hits = self.splats.intersect4(&Rays4::new(rays));
        std::array::from_fn(|l| {
            let ray = rays[l]?;
            let best = lane_prim(hits.idf[l]).map(|id| {
                let uv = [hits.s[l], hits.v[l]];
                (id, ShapeHit { t: hits.t[l], uv })
            });
            self.search_others::<false>(ray, hits.t[l], best)
        })
    }

    /// The closest hit, or with ANY, the first found.
    #[inline]
    fn search<const ANY: bool>(&self, ray: &Ray) -> Option<(PrimId, ShapeHit)> {
        let mut best: Option<(PrimId, ShapeHit)> = None;
        let mut t_max = ray.t_max;
        let r = RayLanes {
            o: splat3(ray.o),
            d: splat3(ray.d),
            origin: Vec4::splat(prim_f32(ray.origin_prim)),
            target: Vec4::splat(prim_f32(ray.target_prim)),
        };
        let padding = Vec4::splat(-1.0);
        for q in &self.quads {
            let (hit, t, s, v) = quad_hits(&r, &q.lanes, Vec4::splat(t_max));
            let hit = hit & q.lanes.idf.cmpne(padding);
            if hit.any() {
                let tt = Vec4::select(hit, t, Vec4::INFINITY);
                let lane = argmin(tt);
                t_max = tt[lane];
                best = Some((
                    q.id[lane],
                    ShapeHit {
                        t: t_max,
                        uv: [s[lane], v[lane]],
                    },
                ));
                if ANY {
                    return best;
                }
            }
        }
        for sp in &self.spheres {
            let Some((hit, t)) = sphere_hits(&r, &sp.lanes, Vec4::splat(t_max)) else {
                continue;
            };
            let hit = hit & sp.lanes.idf.cmpne(padding);
            if hit.any() {
                let tt = Vec4::select(hit, t, Vec4::INFINITY);
                let lane = argmin(tt);
                t_max = tt[lane];
                best = Some((
                    sp.id[lane],
                    ShapeHit {
                        t: t_max,
                        uv: [0.0, 0.0],
                    },
                ));
                if ANY {
                    return best;
                }
            }
        }
        self.search_others::<ANY>(ray, t_max, best)
    }

    /// The triangles' part of a search whose closest quad or sphere hit so far is `best`,
    /// at `t_max` (the ray's own without one). Always inlined: with `#[inline]` alone the
    /// one-ray search no longer compiled as one piece and the camera pass was slower
    /// (measured: docs/performance-history.md, "inlining the triangles' search").
    fn search_others<const ANY: bool>(
        &self,
        ray: &Ray,
        t_max: f32,
        mut best: Option<(PrimId, ShapeHit)>,
    ) -> Option<(PrimId, ShapeHit)> {
        let mut probe = *ray;
        probe.t_max = t_max;
        for (id, s) in &self.others {
            if let Some(h) = s.intersect(&probe, *id) {
                probe.t_max = h.t;
                best = Some((*id, h));
                if ANY {
                    return best;
                }
            }
        }
        best
    }
}

/// The lane of the smallest value (the first, of equal ones).
#[inline]
fn argmin(v: Vec4) -> usize {
    let m = v.min_element();
    (0..4).find(|&i| v[i] == m).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream, uniform_sphere};

    /// The SIMD tests agree with the scalar ones of `shapes.rs` on random rays, and the
    /// four-ray tests with the one-ray ones.
    #[test]
    fn matches_scalar_intersection() {
        let shapes = vec![
            Shape::quad(
                Vec3A::new(-1.0, 0.0, -1.0),
                Vec3A::new(0.0, 0.0, 2.0),
                Vec3A::new(2.0, 0.0, 0.0),
            ),
            Shape::quad(
                Vec3A::new(-1.0, 2.0, -1.0),
                Vec3A::new(2.0, 0.0, 0.0),
                Vec3A::new(0.0, 0.0, 2.0),
            ),
            Shape::quad(
                Vec3A::new(-1.0, 0.0, -1.0),
                Vec3A::new(2.0, 0.0, 0.0),
                Vec3A::new(0.0, 2.0, 0.0),
            ),
            Shape::quad(
                Vec3A::new(-1.0, 0.0, -1.0),
                Vec3A::new(0.0, 2.0, 0.0),
                Vec3A::new(0.0, 0.0, 2.0),
            ),
            Shape::quad(
                Vec3A::new(1.0, 0.0, -1.0),
                Vec3A::new(0.0, 0.0, 2.0),
                Vec3A::new(0.0, 2.0, 0.0),
            ),
            Shape::Sphere {
                center: Vec3A::new(-0.4, 0.35, -0.3),
                radius: 0.35,
            },
            Shape::Sphere {
                center: Vec3A::new(0.45, 0.35, 0.3),
                radius: 0.35,
            },
            Shape::Sphere {
                center: Vec3A::new(0.0, 1.5, 0.0),
                radius: 0.05,
            },
            // Triangles are tested one by one after the lanes.
            Shape::Triangle {
                p0: Vec3A::new(-0.5, 0.2, 0.5),
                p1: Vec3A::new(0.6, 0.4, 0.4),
                p2: Vec3A::new(0.0, 1.2, -0.2),
            },
        ];
        let flat = Flat::new(&shapes);
        let mut s = Sampler::new(1, Stream::Camera, 0);
        let mut lanes = [None; 4];
        for i in 0..50_000 {
            let o = Vec3A::new(
                s.next_f32() * 1.8 - 0.9,
                s.next_f32() * 1.8 + 0.1,
                s.next_f32() * 1.8 - 0.9,
            );
            let mut ray = Ray::new(o, uniform_sphere(s.next_2d()));
            if i % 3 == 0 {
                ray.origin_prim = (i % 9) as u32;
            }
            if i % 7 == 0 {
                ray.target_prim = (i % 5) as u32;
            }
            let mut probe = ray;
            let mut want: Option<(u32, f32)> = None;
            for (id, sh) in shapes.iter().enumerate() {
                if let Some(h) = sh.intersect(&probe, id as u32) {
                    probe.t_max = h.t;
                    want = Some((id as u32, h.t));
                }
            }
            // Four lanes at a time, one idle now and then: each lane, bit for bit, the
            // one-ray answer.
            let lane = i % 4;
            lanes[lane] = (i % 11 != 0).then_some(ray);
            if lane == 3 {
                let bits = |h: Option<(PrimId, ShapeHit)>| {
                    h.map(|(id, h)| (id, h.t.to_bits(), h.uv.map(f32::to_bits)))
                };
                let four = flat.intersect4(lanes.each_ref().map(Option::as_ref));
                for l in 0..4 {
                    let one = lanes[l].and_then(|r| flat.intersect(&r));
                    assert_eq!(bits(four[l]), bits(one), "ray {i}, lane {l}");
                }
            }
            let got = flat.intersect(&ray).map(|(id, h)| (id, h.t));
            assert_eq!(flat.occluded(&ray), want.is_some(), "ray {i}: occlusion");
            if i % 2 == 0 {
                // Shadow rays end short of their target.
                let mut short = ray;
                short.t_max = want.map_or(1.0, |w| w.1 * 0.5);
                let blocked = shapes
                    .iter()
                    .enumerate()
                    .any(|(id, sh)| sh.intersect(&short, id as u32).is_some());
                assert_eq!(flat.occluded(&short), blocked, "ray {i}: short occlusion");
            }
            match (got, want) {
                (Some((gi, gt)), Some((wi, wt))) => {
                    assert!(
                        (gt - wt).abs() <= 1e-5 * wt.max(1.0),
                        "ray {i}: t {gt} vs {wt}"
                    );
                    assert!(
                        gi == wi || (gt - wt).abs() <= 1e-6,
                        "ray {i}: prim {gi} vs {wi}"
                    );
                }
                (g, w) => assert_eq!(g.is_some(), w.is_some(), "ray {i}: {g:?} vs {w:?}"),
            }
        }
    }
}
