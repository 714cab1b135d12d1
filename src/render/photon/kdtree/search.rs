//! The branch-and-bound walks behind every search of the tree (Friedman, Bentley and Finkel
//! 1977): from the root, or climbing from an item's own leaf.

use std::cmp::Ordering;

use glam::Vec3A;

use super::lanes::{distances4, within4};
use super::{KdItem, KdTree, LEAF, Stack, halves};

/// Where a small-k search starts.
#[derive(Clone, Copy, Debug)]
pub(super) enum Start {
    /// At the root, descending on the query's coordinates.
    Root,
    /// At this item's leaf (the query is at the item), climbing.
    Item(u32),
}

/// (squared distance, index) order: nearer first, ties to the lower index.
#[inline]
pub(in crate::render::photon) fn by_distance_then_index(
    a: &(f32, u32),
    b: &(f32, u32),
) -> Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

/// Offer `key` (squared distance, index) to `found`, the k best so far, sorted: it enters if
/// fewer than k are found and it lies strictly within `r2_max`, or if it precedes the k-th,
/// and then only if `passes()`. Returns the k-th distance, the search's new bound, once k
/// are found. Every small-k search here and in `point_grid` takes its candidates this way,
/// so they agree on ties.
#[inline]
pub(in crate::render::photon) fn offer_k_best(
    found: &mut Vec<(f32, u32)>,
    k: usize,
    r2_max: f32,
    key: (f32, u32),
    passes: impl FnOnce() -> bool,
) -> Option<f32> {
    let enters = if found.len() < k {
        key.0 < r2_max
    } else {
        by_distance_then_index(&key, &found[k - 1]).is_lt()
    };
    if !(enters && passes()) {
        return None;
    }
    if found.len() == k {
        found.pop();
    }
    let pos = found.partition_point(|f| by_distance_then_index(f, &key).is_lt());
    found.insert(pos, key);
    (found.len() == k).then(|| found[k - 1].0)
}

impl<T: KdItem> KdTree<T> {
    /// The whole tree as a subtree: (node, lo, hi).
    #[inline]
    pub(super) fn root(&self) -> (u32, u32, u32) {
        (0, 0, self.items.len() as u32)
    }

    /// [`KdTree::knn`] for small k, by branch and bound (Friedman, Bentley and Finkel 1977):
    /// the k best so far, sorted, bound the search. Same answer as the radius-bounded
    /// gather (ties by index); for k of a few, a radius guessed from the last query is a
    /// poor bet, as the distance to the 2nd nearest photon varies widely between
    /// neighbouring queries (see `SMALL_K`).
    pub(super) fn knn_bounded(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        found: &mut Vec<(f32, u32)>,
        start: Start,
    ) -> f32 {
        let mut scan = |item: &T, d2: f32, i: u32, bound: &mut f32| {
            if let Some(b) = offer_k_best(found, k, r2_max, (d2, i), || filter(item)) {
                *bound = b;
            }
        };
        let bound = match start {
            Start::Root => self.branch_and_bound(q, self.root(), r2_max, &mut scan),
            Start::Item(i) => self.climb(q, i, r2_max, &mut scan),
        };
        if found.len() == k { bound } else { r2_max }
    }

    /// Branch and bound (Friedman, Bentley and Finkel 1977), the walk every search here
    /// makes: leaves are visited nearest first, and `scan(item, d2, index, bound)` sees
    /// their items and may lower `bound`; subtrees across a plane farther than sqrt(bound)
    /// are skipped (`>`: at exactly the bound, an item as near as the k-th but with a lower
    /// index may lie across the plane). Returns the final bound. Iterative, with the far
    /// children on a small stack: a recursive version was slower (measured:
    /// docs/performance-history.md, "iterative branch and bound").
    ///
    /// The contract with `scan`: it never raises `bound`, and it accepts no item farther
    /// than the bound as it stands. The leaf scan relies on both: it passes only items within
    /// the bound as it was at the start of each group of four (never a NaN distance), so an
    /// item may still arrive after the bound has dropped below it, and must be refused.
    #[inline]
    pub(super) fn branch_and_bound(
        &self,
        q: Vec3A,
        (node, lo, hi): (u32, u32, u32),
        mut bound: f32,
        scan: &mut impl FnMut(&T, f32, u32, &mut f32),
    ) -> f32 {
        let mut stack = Stack::new();
        stack.push((node, lo, hi, 0.0));
        while let Some((node, lo, hi, plane_d2)) = stack.pop() {
            if plane_d2 > bound {
                continue;
            }
            let (lo, hi) = self.descend(q, (node, lo, hi), bound, &mut stack);
            self.scan_leaf(q, lo, hi, &mut bound, scan);
        }
        bound
    }

    /// Branch and bound from item `at`'s leaf upward: scan that leaf, then, from the
    /// deepest ancestor to the root, search each ancestor's other child whose splitting
    /// plane lies within the bound (its items are all at least that far). The leaf is found
    /// by index, so the descent's comparisons on the query's coordinates, and the far
    /// children it stacks, are saved; the rest is `branch_and_bound`'s contract.
    fn climb(
        &self,
        q: Vec3A,
        at: u32,
        mut bound: f32,
        scan: &mut impl FnMut(&T, f32, u32, &mut f32),
    ) -> f32 {
        let mut path = Stack::new();
        let (mut node, mut lo, mut hi) = (0u32, 0u32, self.items.len() as u32);
        while (hi - lo) as usize > LEAF {
            path.push((node, lo, hi));
            let mid = halves(lo as usize, hi as usize) as u32;
            if at < mid {
                (node, hi) = (2 * node + 1, mid);
            } else {
                (node, lo) = (2 * node + 2, mid);
            }
        }
        self.scan_leaf(q, lo, hi, &mut bound, scan);
        while let Some((parent, lo, hi)) = path.pop() {
            let s = self.splits[parent as usize];
            let d = q[s.axis as usize] - s.value;
            if d * d <= bound {
                let mid = halves(lo as usize, hi as usize) as u32;
                let other = if at < mid {
                    (2 * parent + 2, mid, hi)
                } else {
                    (2 * parent + 1, lo, mid)
                };
                bound = self.branch_and_bound(q, other, bound, scan);
            }
        }
        bound
    }

    /// `scan` on the items of `lo..hi` within `bound` of `q` (see `branch_and_bound` for the
    /// contract). Most items of a leaf lie beyond the bound: their distances are computed
    /// four at a time, and only the items within it go to `scan`: renders are faster than
    /// with one distance and one call per item, with bit-identical images (measured:
    /// docs/performance-history.md, "kd-tree leaf scan four at a time").
    #[inline(always)]
    fn scan_leaf(
        &self,
        q: Vec3A,
        lo: u32,
        hi: u32,
        bound: &mut f32,
        scan: &mut impl FnMut(&T, f32, u32, &mut f32),
    ) {
        let leaf = &self.items[lo as usize..hi as usize];
        let (fours, rest) = leaf.as_chunks::<4>();
        let mut at = lo;
        for four in fours {
            let d2 = distances4(q, four);
            let mask = within4(d2, *bound);
            if mask != 0 {
                for (j, item) in four.iter().enumerate() {
                    if mask & (1 << j) != 0 {
                        scan(item, d2[j], at + j as u32, bound);
                    }
                }
            }
            at += 4;
        }
        for (j, item) in rest.iter().enumerate() {
            let d2 = (item.position() - q).length_squared();
            if d2 <= *bound {
                scan(item, d2, at + j as u32, bound);
            }
        }
    }

    /// From the subtree `(node, lo, hi)` down to the leaf on `q`'s side; every far child
    /// whose plane lies within sqrt(`bound`) waits on `stack` with its squared plane
    /// distance. Returns the leaf's item range. (Every search here starts this way.)
    #[inline]
    fn descend(
        &self,
        q: Vec3A,
        (mut node, mut lo, mut hi): (u32, u32, u32),
        bound: f32,
        stack: &mut Stack<(u32, u32, u32, f32)>,
    ) -> (u32, u32) {
        while (hi - lo) as usize > LEAF {
            let mid = halves(lo as usize, hi as usize) as u32;
            let s = self.splits[node as usize];
            let d = q[s.axis as usize] - s.value;
            let (near, far) = if d < 0.0 {
                ((2 * node + 1, lo, mid), (2 * node + 2, mid, hi))
            } else {
                ((2 * node + 2, mid, hi), (2 * node + 1, lo, mid))
            };
            if d * d <= bound {
                stack.push((far.0, far.1, far.2, d * d));
            }
            (node, lo, hi) = near;
        }
        (lo, hi)
    }
}
