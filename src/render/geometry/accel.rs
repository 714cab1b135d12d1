//! The ray-intersection acceleration structure: obvhs's compressed 8-wide BVH (Ylitie et
//! al. 2017, built by PLOC, Meister and Bittner 2018) over our own primitives.
//!
//! obvhs is built single-threaded (its `parallel` feature is off) so that the tree, and with
//! it the order in which equal-distance hits are found, never depends on the thread count.

use std::ops::ControlFlow;
use std::time::Duration;

use glam::{UVec2, Vec3A, Vec4};

use obvhs::{
    Boundable, BvhBuildParams,
    aabb::Aabb,
    cwbvh::{CwBvh, builder::build_cwbvh, bvh2_to_cwbvh::bvh2_to_cwbvh},
    ray::Ray as BvhRay,
    traverse,
};

use super::degenerate;
use super::flat::Flat;
use super::triangle::intersect_triangle;
use super::{Hit, PrimId, Primitive, Ray, Shape, shapes::ShapeHit};
use crate::render::stack::Stack;

impl Boundable for Primitive {
    fn aabb(&self) -> Aabb {
        self.shape.bounds()
    }
}

/// Scenes of at most this many primitives are tested one by one: for the seed's boxes of a
/// few quads and spheres, a BVH culls almost nothing and costs a traversal, so a linear scan
/// is cheaper per camera ray (measured: docs/performance-history.md, "BVH or linear scan").
const FLAT_MAX: usize = 16;

/// Where a ray first meets a primitive.
#[derive(Clone, Copy, Debug)]
pub struct PrimHit {
    prim: PrimId,
    hit: ShapeHit,
}

/// All primitives of a scene, reordered to the BVH's leaf order so that a leaf's primitive
/// index is the primitive's id (no BVH for tiny scenes).
pub struct Accel {
    bvh: Option<CwBvh>,
    flat: Option<Flat>,
    prims: Vec<Primitive>,
    /// What the BVH's leaf tests read, in leaf order ([`Corners`]); empty without a BVH.
    leaves: Vec<Corners>,
    /// Built top-down because PLOC would have stalled (see [`build_bvh`]).
    top_down: bool,
}

/// The wide BVH over `prims` (more than [`FLAT_MAX`]): PLOC as obvhs builds it, unless its
/// dry run says PLOC would stall on these boxes (`degenerate.rs`: copies of one triangle,
/// nested ones; quadratic there), then a top-down build, whose cost is O(n log n) whatever
/// the boxes. Both are deterministic; only degenerate scenes take the second.
fn build_bvh(prims: &[Primitive]) -> (CwBvh, bool) {
    let params = BvhBuildParams::medium_build();
    let boxes: Vec<Aabb> = prims.iter().map(Boundable::aabb).collect();
    if degenerate::stalls_ploc(&boxes) {
        let bvh2 = degenerate::build_top_down(&boxes);
        // No reinsertion pass: its search for a better place for a node prunes by box
        // overlap, which is what such scenes have everywhere.
        let max_leaf = params.max_prims_per_leaf.clamp(1, 3);
        return (bvh2_to_cwbvh(&bvh2, max_leaf, true, false), true);
    }
    let mut build_time = Duration::ZERO;
    (build_cwbvh(prims, params, &mut build_time), false)
}

impl Accel {
    pub fn build(prims: Vec<Primitive>) -> Accel {
        if prims.len() <= FLAT_MAX {
            let shapes: Vec<_> = prims.iter().map(|p| p.shape).collect();
            return Accel {
                bvh: None,
                flat: Some(Flat::new(&shapes)),
                prims,
                leaves: Vec::new(),
                top_down: false,
            };
        }
        let (mut bvh, top_down) = build_bvh(&prims);
        let ordered: Vec<Primitive> = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        drop(prims); // before the leaves are made: the peak stays what it was
        // The leaves now index `ordered` directly.
        for (i, idx) in bvh.primitive_indices.iter_mut().enumerate() {
            *idx = i as u32;
        }
        Accel {
            bvh: Some(bvh),
            flat: None,
            leaves: ordered.iter().map(Corners::of).collect(),
            prims: ordered,
            top_down,
        }
    }

    /// Whether the BVH was built top-down for degenerate geometry rather than by PLOC.
    pub fn built_top_down(&self) -> bool {
        self.top_down
    }

    /// The primitives in leaf order (a primitive's id is its index here).
    pub fn prims(&self) -> &[Primitive] {
        &self.prims
    }

    /// The closest hit along the ray, if any.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.closest(ray).map(|c| self.hit_point(ray, c))
    }

    /// The primitive the ray meets first, before its surface point is worked out.
    fn closest(&self, ray: &Ray) -> Option<PrimHit> {
        let Some(bvh) = self.bvh.as_ref() else {
            let (prim, hit) = self.flat.as_ref()?.intersect(ray)?;
            return Some(PrimHit { prim, hit });
        };
        let mut best: Option<PrimHit> = None;
        self.walk(bvh, ray, |bray, id| {
            let mut probe = *ray;
            probe.t_max = bray.tmax;
            if let Some(hit) = self.leaf_hit(id, &probe) {
                best = Some(PrimHit { prim: id, hit });
                bray.tmax = bray.tmax.min(hit.t);
            }
            ControlFlow::Continue(())
        });
        best
    }

    /// The surface point of `ray`'s closest hit `c`.
    #[inline]
    pub fn hit_point(&self, ray: &Ray, c: PrimHit) -> Hit {
        let point = self.prims[c.prim as usize]
            .shape
            .surface_point(ray, &c.hit, c.prim);
        Hit { t: c.hit.t, point }
    }

    /// [`Accel::intersect`] for up to four rays (None: an idle lane, which gets None), the
    /// surface points left to [`Accel::hit_point`]. A tiny scene tests the four together
    /// (`packet.rs`); the answers are the same as one by one.
    #[inline]
    pub fn closest4(&self, rays: [Option<&Ray>; 4]) -> [Option<PrimHit>; 4] {
        let Some(flat) = self.flat.as_ref() else {
            return rays.map(|r| r.and_then(|r| self.closest(r)));
        };
        flat.intersect4(rays)
            .map(|h| h.map(|(prim, hit)| PrimHit { prim, hit }))
    }

    /// Walks the BVH along `ray` with obvhs's `traverse!` (its node order), handing `leaf`
    /// each primitive in a box the ray meets within `tmax`; `leaf` may shorten `tmax` (the
    /// closest hit) or end the walk (any hit).
    #[inline(always)]
    fn walk(
        &self,
        bvh: &CwBvh,
        ray: &Ray,
        mut leaf: impl FnMut(&mut BvhRay, PrimId) -> ControlFlow<()>,
    ) {
        let mut bray = BvhRay::new(ray.o, ray.d, 0.0, ray.t_max);
        let mut state = Traversal::new(bvh, ray.d);
        let mut node;
        'walk: {
            traverse!(
                bvh,
                node,
                state,
                node.intersect_ray(&bray, state.oct_inv4),
                {
                    if leaf(&mut bray, state.primitive_id).is_break() {
                        break 'walk;
                    }
                }
            );
        }
    }

    /// [`Shape::intersect`] for the primitive of BVH leaf slot `id`, a triangle's from its
    /// packed corners.
    #[inline(always)]
    fn leaf_hit(&self, id: PrimId, ray: &Ray) -> Option<ShapeHit> {
        let [p0, p1, p2] = self.leaves[id as usize].0;
        if p0.w == 0.0 {
            return self.prims[id as usize].shape.intersect(ray, id);
        }
        // Shape::intersect's own tests for a triangle, in its order.
        if ray.target_prim == id || ray.origin_prim == id {
            return None;
        }
        let corner = Vec3A::from_vec4;
        intersect_triangle(corner(p0), corner(p1), corner(p2), ray)
    }

    /// Whether anything blocks the ray before `ray.t_max` (shadow rays).
    pub fn occluded(&self, ray: &Ray) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return self.flat.as_ref().is_some_and(|f| f.occluded(ray));
        };
        let mut blocked = false;
        self.walk(bvh, ray, |bray, id| {
            if self.leaf_hit(id, ray).is_some_and(|h| h.t < bray.tmax) {
                blocked = true;
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        });
        blocked
    }
}

/// obvhs's traversal state (the fields its `traverse!` reads) over our unzeroed stack: its
/// own `ray_traverse` zeroes a 256-byte stack for every ray (docs/performance-history.md,
/// "unzeroed BVH stack"). Same nodes, same order, so the same hits.
struct Traversal {
    stack: Stack<UVec2, 32>,
    current_group: UVec2,
    primitive_group: UVec2,
    oct_inv4: u32,
    primitive_id: u32,
    hitmask: u32,
}

impl Traversal {
    #[inline]
    fn new(bvh: &CwBvh, dir: Vec3A) -> Traversal {
        let empty = bvh.nodes.is_empty();
        Traversal {
            stack: Stack::new(),
            current_group: if empty {
                UVec2::ZERO
            } else {
                UVec2::new(0, 0x8000_0000)
            },
            primitive_group: UVec2::ZERO,
            // The ray's octant, inverted, in every byte (obvhs's `ray_get_octant_inv4`).
            oct_inv4: (if dir.x < 0.0 { 0 } else { 0x0404_0404 })
                | (if dir.y < 0.0 { 0 } else { 0x0202_0202 })
                | (if dir.z < 0.0 { 0 } else { 0x0101_0101 }),
            primitive_id: 0,
            hitmask: 0,
        }
    }
}

/// A BVH leaf's primitive as the traversal reads it: a triangle's three corners, 48 bytes
/// against a [`Primitive`]'s 128, so that a mesh's leaves take fewer cache lines (reading
/// the primitive was the hottest instruction of `Accel::closest` in a knot render); w = 1
/// marks a triangle, w = 0 any other shape, read from the primitive itself.
#[derive(Clone, Copy)]
struct Corners([Vec4; 3]);

impl Corners {
    fn of(p: &Primitive) -> Corners {
        match p.shape {
            Shape::Triangle { p0, p1, p2 } => Corners([p0, p1, p2].map(|c| c.extend(1.0))),
            _ => Corners([Vec4::ZERO; 3]),
        }
    }
}
