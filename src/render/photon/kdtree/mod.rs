//! A static balanced kd-tree (Bentley 1975; as photon maps use it, Jensen 2001, section 6.3)
//! laid out for cache efficiency: the items are reordered in place into leaf buckets of at
//! most LEAF items, and the splitting planes live in a separate compact array in heap order
//! (node i has children 2i+1 and 2i+2), so the top of the tree shares a few cache lines
//! and a query touches item memory only in the leaves it scans. The items carry nothing for
//! the tree: a photon stays 28 bytes, plus 8 bytes of split per LEAF photons. Balancing is
//! in `build.rs`.
//!
//! Searches: for k above SMALL_K, k-nearest-neighbour queries gather every item within a
//! guessed radius and select the k nearest with `select_nth_unstable` (ties broken by
//! index, so the answer never depends on the guess); the guess is the previous query's
//! radius on the same thread, which for the spatially coherent queries of a render (pixels
//! of a tile, photons in tree order) is nearly right. This "radius-bounded gather" beats a
//! heap-based search by several times at k = 50-100. Small k, the nearest item and the
//! range search walk the tree by branch and bound; every search scans its leaves four
//! items at a time (`lanes.rs`).
//!
//! Chosen over kiddo after measuring both on photon maps (benches/kdtree.rs, recorded in
//! docs/performance.md).

use std::cmp::Ordering;
use std::mem::MaybeUninit;

use glam::Vec3A;

use lanes::{distances4, within4};

mod build;
mod lanes;
#[cfg(test)]
mod tests;

/// An item the tree can hold.
pub trait KdItem: Copy + Send + Sync {
    fn position(&self) -> Vec3A;

    /// One coordinate of the position (overridden where that is cheaper).
    #[inline]
    fn coord(&self, axis: usize) -> f32 {
        self.position()[axis]
    }
}

/// Ranges of at most this many items are leaves. 16 rather than 8 spares the build its
/// deepest level of small selections: on scene 1 (100k + 100k photons, perf-tables, two
/// alternating runs each) the global map's build after tracing took 6.0-6.9 ms against
/// 8.0-8.3, a ppm pass 178-180 ms against 184-188, and k-NN renders were unchanged.
const LEAF: usize = 16;

/// Up to this k, k-NN queries search by branch and bound rather than by a guessed radius.
/// Measured on the irradiance precomputation's queries (scene 1, 100k photons, one thread),
/// branch and bound against the gather: k = 2: 620 vs 852 ns, k = 8: 1584 vs 1694 ns,
/// k = 11: 2076 vs 1979 ns, k = 32: 5345 vs 3292 ns.
const SMALL_K: usize = 8;

/// The next query's radius guess is this factor (in area) above the last one's result.
const GUESS_SLACK: f32 = 1.3;

/// A splitting plane: items left of it have coordinate <= value on `axis`, right >= value.
#[derive(Clone, Copy, Debug, Default)]
struct Split {
    value: f32,
    axis: u32,
}

pub struct KdTree<T: KdItem> {
    items: Vec<T>,
    splits: Vec<Split>,
    /// Items per unit area, from the bounding box's surface: a first radius guess.
    density_hint: f32,
}

/// Per-thread scratch for k-NN queries: the candidate buffer and the radius guess.
#[derive(Default)]
pub struct KnnScratch {
    found: Vec<(f32, u32)>,
    r2_guess: f32,
}

impl KnnScratch {
    /// The items found by the last query, as (squared distance, index). When it found k,
    /// the last entry is the k-th nearest.
    pub fn found(&self) -> &[(f32, u32)] {
        &self.found
    }
}

#[inline]
fn by_distance_then_index(a: &(f32, u32), b: &(f32, u32)) -> Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

/// The two halves of a node's range: the median starts the right half.
#[inline]
fn halves(lo: usize, hi: usize) -> usize {
    lo + (hi - lo) / 2
}

impl<T: KdItem> KdTree<T> {
    pub fn items(&self) -> &[T] {
        &self.items
    }

    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Bytes of the tree's own structure (the splits), beyond the items.
    pub fn overhead_bytes(&self) -> usize {
        self.splits.len() * std::mem::size_of::<Split>()
    }

    /// The k nearest items that pass `filter` within sqrt(r2_max) of `q` (all of them if
    /// fewer), into `scratch.found()`. Returns the squared radius the result stands for: the
    /// k-th distance if k were found, else `r2_max`.
    pub fn knn(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        scratch: &mut KnnScratch,
    ) -> f32 {
        scratch.found.clear();
        if k == 0 || self.items.is_empty() {
            return r2_max;
        }
        if k <= SMALL_K {
            return self.knn_bounded(q, k, r2_max, filter, &mut scratch.found);
        }
        let guess = if scratch.r2_guess > 0.0 {
            scratch.r2_guess
        } else {
            GUESS_SLACK * k as f32 / (std::f32::consts::PI * self.density_hint)
        };
        let mut r2 = if guess > 0.0 && guess < r2_max {
            guess
        } else {
            r2_max
        };
        loop {
            scratch.found.clear();
            let found = &mut scratch.found;
            self.within(q, r2, &mut |item, d2, idx| {
                if filter(item) {
                    found.push((d2, idx));
                }
            });
            if found.len() >= k {
                found.select_nth_unstable_by(k - 1, by_distance_then_index);
                found.truncate(k);
                // select_nth leaves the k-th at k-1 with everything before it nearer.
                let rk = found[k - 1].0;
                scratch.r2_guess = (rk * GUESS_SLACK).max(f32::MIN_POSITIVE);
                return rk;
            }
            if r2 >= r2_max {
                // Sparse here: the next query (nearby) starts at the bound, in one step.
                scratch.r2_guess = r2_max;
                return r2_max;
            }
            // Too few: grow the guess; a fourfold area covers most misses in one step.
            r2 = (r2 * 4.0).min(r2_max);
        }
    }

    /// [`KdTree::knn`] for small k, by branch and bound (Friedman, Bentley and Finkel 1977):
    /// the k best so far, sorted, bound the search. Same answer as the radius-bounded
    /// gather (ties by index); for k of a few, a radius guessed from the last query is a
    /// poor bet, as the distance to the 2nd nearest photon varies widely between
    /// neighbouring queries (see `SMALL_K`).
    fn knn_bounded(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        found: &mut Vec<(f32, u32)>,
    ) -> f32 {
        // While fewer than k are found, anything strictly within the bound enters.
        let bound = self.branch_and_bound(q, r2_max, &mut |item, d2, i, bound| {
            let enters = if found.len() < k {
                d2 < r2_max
            } else {
                by_distance_then_index(&(d2, i), &found[k - 1]) == Ordering::Less
            };
            if enters && filter(item) {
                if found.len() == k {
                    found.pop();
                }
                let at = found.partition_point(|f| by_distance_then_index(f, &(d2, i)).is_lt());
                found.insert(at, (d2, i));
                if found.len() == k {
                    *bound = found[k - 1].0;
                }
            }
        });
        if found.len() == k { bound } else { r2_max }
    }

    /// Call `visit(item, d2, index)` for every item within sqrt(r2) of `q` (strictly).
    #[inline]
    pub fn within(&self, q: Vec3A, r2: f32, visit: &mut impl FnMut(&T, f32, u32)) {
        // Subtrees across a plane at exactly sqrt(r2) are visited too; none of their items
        // is strictly within.
        self.branch_and_bound(q, r2, &mut |item, d2, i, _| {
            if d2 < r2 {
                visit(item, d2, i);
            }
        });
    }

    /// Branch and bound (Friedman, Bentley and Finkel 1977), the walk every search here
    /// makes: leaves are visited nearest first, and `scan(item, d2, index, bound)` sees
    /// their items and may lower `bound`; subtrees across a plane farther than sqrt(bound)
    /// are skipped (`>`: at exactly the bound, an item as near as the k-th but with a lower
    /// index may lie across the plane). Returns the final bound. Iterative, with the far
    /// children on a small stack: a recursive version measured 1.5x slower.
    ///
    /// The contract with `scan`: it never raises `bound`, and it accepts no item farther
    /// than the bound as it stands. The leaf scan relies on both: it passes only items within
    /// the bound as it was at the start of each group of four (never a NaN distance), so an
    /// item may still arrive after the bound has dropped below it, and must be refused.
    #[inline]
    fn branch_and_bound(
        &self,
        q: Vec3A,
        mut bound: f32,
        scan: &mut impl FnMut(&T, f32, u32, &mut f32),
    ) -> f32 {
        let mut stack = Stack::new();
        stack.push((0, 0, self.items.len() as u32, 0.0));
        while let Some((node, lo, hi, plane_d2)) = stack.pop() {
            if plane_d2 > bound {
                continue;
            }
            let (lo, hi) = self.descend(q, (node, lo, hi), bound, &mut stack);
            self.scan_leaf(q, lo, hi, &mut bound, scan);
        }
        bound
    }

    /// `scan` on the items of `lo..hi` within `bound` of `q` (see `branch_and_bound` for the
    /// contract). Most items of a leaf lie beyond the bound: their distances are computed
    /// four at a time, and only the items within it go to `scan`. Against one distance and
    /// one call per item, on scene 1 (perf-tables, two alternating rounds, with a first
    /// version of `lanes.rs` in SSE2 intrinsics; the `Vec4` one measured the same or better):
    /// render at k = 1 112.9 / 112.5 -> 110.8 / 106.9 ms, at k = 100 220.2 / 218.3 -> 215.5 /
    /// 213.0 ms; images bit-identical.
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

    /// The nearest item passing `filter` within sqrt(r2_max), as (index, squared distance);
    /// of equally near items, the one with the lowest index. `hint` is an index to try first
    /// (usually the previous query's answer): a near hint shrinks the search, and the answer
    /// does not depend on it.
    pub fn nearest(
        &self,
        q: Vec3A,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        hint: Option<u32>,
    ) -> Option<(u32, f32)> {
        let mut best: Option<(u32, f32)> = None;
        let mut r2 = r2_max;
        if let Some(h) = hint.filter(|&h| (h as usize) < self.items.len()) {
            let item = &self.items[h as usize];
            let d2 = (item.position() - q).length_squared();
            if d2 < r2 && filter(item) {
                best = Some((h, d2));
                r2 = d2;
            }
        }
        self.branch_and_bound(q, r2, &mut |item, d2, i, r2| {
            let better = match best {
                Some((bi, bd2)) => d2 < bd2 || (d2 == bd2 && i < bi),
                None => d2 < *r2,
            };
            if better && filter(item) {
                best = Some((i, d2));
                *r2 = d2;
            }
        });
        best
    }
}

/// Deeper than any tree of up to 2^32 items with LEAF-sized leaves.
const MAX_DEPTH: usize = 64;

/// A fixed-capacity stack for traversals that is not zeroed on creation: a zeroed 1 KiB
/// array per query showed up as 7% of a render in memset.
struct Stack<T: Copy> {
    items: [MaybeUninit<T>; MAX_DEPTH],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline]
    fn new() -> Self {
        Stack {
            items: [const { MaybeUninit::uninit() }; MAX_DEPTH],
            len: 0,
        }
    }

    #[inline]
    fn push(&mut self, v: T) {
        // Indexing panics rather than overflow (impossible for a balanced tree).
        self.items[self.len] = MaybeUninit::new(v);
        self.len += 1;
    }

    #[inline]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}
