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
//! [`build_top_down`] builds such scenes top-down instead (binned SAH, Wald 2007, with a
//! median split whenever SAH cannot separate the centroids or would split off less than a
//! sixteenth), whose depth, and so its cost, stays O(n log n) whatever the boxes. Other
//! scenes keep the PLOC build and so their BVH, bit for bit.

use obvhs::{
    aabb::Aabb,
    bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH, node::Bvh2Node},
    ploc::morton::morton_encode_u64_unorm,
};

/// Below this many clusters a sweep is cheap whatever it merges.
const SMALL: usize = 64;

/// A sweep that merges fewer than one pair per this many clusters counts as stalled.
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

/// SAH bins per split.
const BINS: usize = 16;

/// A binary BVH over `boxes` built top-down, one primitive a leaf (as PLOC leaves them: the
/// wide BVH's conversion then gathers leaves by cost). Children are stored after their
/// parent, in adjacent slots, as obvhs expects.
pub fn build_top_down(boxes: &[Aabb]) -> Bvh2 {
    let n = boxes.len();
    let mut bvh = Bvh2 {
        primitive_indices: (0..n as u32).collect(),
        ..Bvh2::default()
    };
    if n == 0 {
        return bvh;
    }
    let centers: Vec<glam::Vec3A> = boxes.iter().map(Aabb::center).collect();
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
        let mid = lo + split(items, &centers, boxes);
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

/// Partition `items` (at least two) and return the size of the left part, in 1..len.
fn split(items: &mut [u32], centers: &[glam::Vec3A], boxes: &[Aabb]) -> usize {
    let n = items.len();
    let cb = items.iter().fold(Aabb::empty(), |mut b, &i| {
        b.extend(centers[i as usize]);
        b
    });
    let axis = cb.largest_axis();
    let (c_lo, extent) = (cb.min[axis], cb.diagonal()[axis]);
    let median = |items: &mut [u32]| {
        let key = |i: &u32| (centers[*i as usize][axis], *i);
        items.select_nth_unstable_by(n / 2, |a, b| {
            let (ka, kb) = (key(a), key(b));
            ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
        });
        n / 2
    };
    if !(extent > 0.0) {
        return median(items);
    }
    let bin_of = |i: u32| {
        let t = (centers[i as usize][axis] - c_lo) / extent * BINS as f32;
        (t as usize).min(BINS - 1)
    };
    let mut count = [0usize; BINS];
    let mut bin_box = [Aabb::empty(); BINS];
    for &i in items.iter() {
        let b = bin_of(i);
        count[b] += 1;
        bin_box[b] = bin_box[b].union(&boxes[i as usize]);
    }
    // SAH over the BINS - 1 planes: area x count on each side.
    let mut right_cost = [0.0f32; BINS];
    let (mut acc, mut k) = (Aabb::empty(), 0);
    for b in (1..BINS).rev() {
        acc = acc.union(&bin_box[b]);
        k += count[b];
        right_cost[b] = if k > 0 {
            acc.half_area() * k as f32
        } else {
            0.0
        };
    }
    let (mut acc, mut k) = (Aabb::empty(), 0);
    let mut best = (f32::INFINITY, 0usize, 0usize);
    for b in 1..BINS {
        acc = acc.union(&bin_box[b - 1]);
        k += count[b - 1];
        let c = if k > 0 {
            acc.half_area() * k as f32
        } else {
            0.0
        } + right_cost[b];
        if k > 0 && k < n && c < best.0 {
            best = (c, b, k);
        }
    }
    let (_, plane, left) = best;
    if left * MIN_MERGE_FRACTION < n || (n - left) * MIN_MERGE_FRACTION < n {
        return median(items);
    }
    // Stable-enough in-place partition: bins below `plane` to the left.
    let mut l = 0;
    for j in 0..n {
        if bin_of(items[j]) < plane {
            items.swap(l, j);
            l += 1;
        }
    }
    debug_assert_eq!(l, left);
    l
}
