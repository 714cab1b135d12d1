//! Degenerate geometry for the BVH build: many primitives whose boxes coincide or nest
//! (copies of one triangle, concentric or stacked triangles, a fan of slivers about one
//! vertex).
//!
//! PLOC (Meister and Bittner 2018) merges, in each sweep over the Morton-sorted clusters,
//! the pairs that are each other's best neighbour. On such input almost no pair is: every
//! box sees the same cost to all its neighbours (ties, which obvhs breaks toward the
//! farthest one) or a cost that falls steadily toward one end of the run (nested boxes), so
//! one sweep merges one pair, and n clusters take n sweeps of O(n) each: 30,000 copies of a
//! triangle took minutes against a fraction of a second for as many distinct ones.
//!
//! [`stalls_ploc`] predicts this in O(n log n) by a dry run of PLOC's simplest form
//! (neighbour distance 1, the rule obvhs itself applies to its first sweeps) and
//! [`build_top_down`] builds such scenes top-down instead, by median splits: depth
//! ceil(log2 n) and cost O(n log n) whatever the boxes. Other scenes keep the PLOC build
//! and so their BVH, bit for bit. The dry run is a model of PLOC, not PLOC: input that
//! stalls only PLOC's wider neighbour search would go unnoticed (none is known).

use glam::Vec3A;
use obvhs::{
    aabb::Aabb,
    bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH, node::Bvh2Node},
    ploc::morton::morton_encode_u64_unorm,
};

/// Below this many clusters a sweep is cheap whatever it merges.
const SMALL: usize = 64;

/// A sweep that merges fewer than one pair per this many clusters counts as stalled.
/// (Ordinary meshes merge about one pair per four clusters a sweep.)
const MIN_MERGE_FRACTION: usize = 16;

/// Whether PLOC would stall on these boxes: some sweep of the dry run over more than
/// [`SMALL`] clusters merges fewer than one pair in [`MIN_MERGE_FRACTION`]. Each passing
/// sweep removes at least a sixteenth of the clusters, so the dry run costs O(n) after its
/// O(n log n) sort.
pub fn stalls_ploc(boxes: &[Aabb]) -> bool {
    let mut nodes = morton_sorted(boxes);
    let mut next = Vec::with_capacity(nodes.len());
    let mut cost = Vec::with_capacity(nodes.len());
    while nodes.len() > SMALL {
        // cost[i]: the box of clusters i and i + 1 (its half area).
        cost.clear();
        cost.extend(nodes.windows(2).map(|w| w[0].union(&w[1]).half_area()));
        // Cluster i prefers its right neighbour unless the pair on its left is cheaper
        // (obvhs's distance-1 rule); i and i + 1 merge when they prefer each other.
        let prefers_right = |i: usize| i + 1 < nodes.len() && (i == 0 || cost[i - 1] >= cost[i]);
        next.clear();
        let mut i = 0;
        while i < nodes.len() {
            if prefers_right(i) && !prefers_right(i + 1) {
                next.push(nodes[i].union(&nodes[i + 1]));
                i += 2;
            } else {
                next.push(nodes[i]);
                i += 1;
            }
        }
        let merged = nodes.len() - next.len();
        if merged * MIN_MERGE_FRACTION < nodes.len() {
            return true;
        }
        std::mem::swap(&mut nodes, &mut next);
    }
    false
}

/// The boxes in the Morton order of their centres (ties by index: deterministic).
fn morton_sorted(boxes: &[Aabb]) -> Vec<Aabb> {
    let bounds = boxes.iter().fold(Aabb::empty(), |mut b, x| {
        b.extend(x.center());
        b
    });
    let scale = 1.0 / bounds.diagonal().as_dvec3().max(glam::DVec3::splat(1e-30));
    let mut keyed: Vec<(u64, u32)> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let unit = (b.center().as_dvec3() - bounds.min.as_dvec3()) * scale;
            (morton_encode_u64_unorm(unit), i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| boxes[i as usize]).collect()
}

/// A binary BVH over `boxes` built top-down by object median splits on the centroids'
/// widest axis, one primitive a leaf (as PLOC leaves them: the wide BVH's conversion then
/// gathers leaves by cost). Median splits keep the depth at ceil(log2 n), which matters
/// beyond speed: obvhs traverses its wide BVH with a stack of 32 entries that silently
/// drops nodes past that depth, and a surface-area split of such boxes can peel them off
/// one at a time. Children are stored after their parent, in adjacent slots, as obvhs
/// expects.
pub fn build_top_down(boxes: &[Aabb]) -> Bvh2 {
    let n = boxes.len();
    let mut bvh = Bvh2 {
        primitive_indices: (0..n as u32).collect(),
        ..Bvh2::default()
    };
    if n == 0 {
        return bvh;
    }
    let centers: Vec<Vec3A> = boxes.iter().map(Aabb::center).collect();
    let mut order: Vec<u32> = (0..n as u32).collect();
    bvh.nodes.reserve(2 * n - 1);
    bvh.nodes.push(Bvh2Node::default());
    // (node slot, range of `order`, depth)
    let mut stack = vec![(0usize, 0usize, n, 1usize)];
    let mut max_depth = 1;
    while let Some((slot, lo, hi, depth)) = stack.pop() {
        max_depth = max_depth.max(depth);
        let items = &mut order[lo..hi];
        let bounds = items
            .iter()
            .fold(Aabb::empty(), |b, &i| b.union(&boxes[i as usize]));
        if items.len() == 1 {
            bvh.nodes[slot] = Bvh2Node::new(bounds, 1, items[0]);
            continue;
        }
        let mid = lo + median_split(items, &centers);
        let first = bvh.nodes.len();
        bvh.nodes.push(Bvh2Node::default());
        bvh.nodes.push(Bvh2Node::default());
        bvh.nodes[slot] = Bvh2Node::new(bounds, 0, first as u32);
        stack.push((first + 1, mid, hi, depth + 1));
        stack.push((first, lo, mid, depth + 1));
    }
    bvh.children_are_ordered_after_parents = true;
    bvh.max_depth = DEFAULT_MAX_STACK_DEPTH.max(max_depth + 1);
    bvh
}

/// Partition `items` (at least two) about the median of their centroids along the widest
/// axis (ties by index: deterministic) and return the size of the left half.
fn median_split(items: &mut [u32], centers: &[Vec3A]) -> usize {
    let cb = items.iter().fold(Aabb::empty(), |mut b, &i| {
        b.extend(centers[i as usize]);
        b
    });
    let axis = cb.largest_axis();
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |&a, &b| {
        let (ca, cb) = (centers[a as usize][axis], centers[b as usize][axis]);
        ca.total_cmp(&cb).then(a.cmp(&b))
    });
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box(c: Vec3A, half: f32) -> Aabb {
        Aabb::new(c - half, c + half)
    }

    /// The depth of the tree under node `i`, checking that each node bounds its children.
    fn depth(bvh: &Bvh2, i: usize) -> usize {
        let node = &bvh.nodes[i];
        if node.prim_count > 0 {
            return 1;
        }
        let f = node.first_index as usize;
        for c in [f, f + 1] {
            let child = bvh.nodes[c].aabb();
            assert_eq!(node.aabb().union(child), *node.aabb(), "node {i} child {c}");
        }
        1 + depth(bvh, f).max(depth(bvh, f + 1))
    }

    #[test]
    fn copies_and_nested_boxes_stall_ploc_and_a_grid_does_not() {
        let copies = vec![unit_box(Vec3A::ZERO, 1.0); 5000];
        let nested: Vec<Aabb> = (0..5000)
            .map(|i| unit_box(Vec3A::ZERO, 1.0 + i as f32 * 1e-3))
            .collect();
        let grid: Vec<Aabb> = (0..5000)
            .map(|i| unit_box(Vec3A::new((i % 70) as f32, (i / 70) as f32, 0.0), 0.3))
            .collect();
        assert!(stalls_ploc(&copies));
        assert!(stalls_ploc(&nested));
        assert!(!stalls_ploc(&grid));
    }

    /// Every primitive in exactly one leaf, boxes nested, and depth ceil(log2 n) + 1.
    #[test]
    fn top_down_tree_is_balanced_and_holds_every_primitive_once() {
        let n = 10_000;
        let boxes: Vec<Aabb> = (0..n)
            .map(|i| unit_box(Vec3A::splat((i % 3) as f32), 1.0 + (i % 5) as f32))
            .collect();
        let bvh = build_top_down(&boxes);
        assert_eq!(bvh.nodes.len(), 2 * n - 1);
        let mut seen = vec![0u32; n];
        for node in bvh.nodes.iter().filter(|b| b.prim_count > 0) {
            seen[node.first_index as usize] += 1;
            assert_eq!(*node.aabb(), boxes[node.first_index as usize]);
        }
        assert!(seen.iter().all(|&k| k == 1));
        assert_eq!(depth(&bvh, 0), 15);
    }
}
