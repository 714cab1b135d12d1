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
//! heap-based search by several times at k = 50-100. Small k and the range search walk
//! the tree by branch and bound (`search.rs`), from the root or, for a query at an item,
//! climbing from the item's leaf; every search scans its leaves four items at a time
//! (`lanes.rs`). The camera pass's per-pixel lookups use uniform grids instead
//! (`photon/point_grid/`), with the same answers.
//!
//! Chosen over kiddo after measuring both on photon maps (benches/kdtree.rs, recorded in
//! docs/performance.md).

use glam::Vec3A;

pub(super) use lanes::{distances4, within4};
use search::Start;
pub(super) use search::{by_distance_then_index, offer_k_best};

mod build;
mod lanes;
mod search;
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
/// deepest level of small selections: builds and ppm passes are faster, k-NN renders
/// unchanged (measured: docs/performance-history.md, "kd-tree leaf size").
const LEAF: usize = 16;

/// Up to this k, k-NN queries search by branch and bound rather than by a guessed radius:
/// on the irradiance precomputation's queries, branch and bound is faster than the gather up
/// to k = 8 and slower from k = 11 (measured: docs/performance-history.md, "branch and
/// bound or guessed radius").
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

    /// The buffer, for searches outside the tree (`photon/point_grid/`).
    pub(in crate::render::photon) fn found_mut(&mut self) -> &mut Vec<(f32, u32)> {
        &mut self.found
    }
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
            return self.knn_bounded(q, k, r2_max, filter, &mut scratch.found, Start::Root);
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

    /// [`KdTree::knn`] at the position of item `at` (the irradiance precomputation's
    /// queries): for small k the search starts in `at`'s own leaf, found by index, and climbs
    /// (see `climb`), instead of descending from the root on the query's coordinates. Same
    /// answer.
    pub fn knn_at(
        &self,
        at: u32,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        scratch: &mut KnnScratch,
    ) -> f32 {
        let q = self.items[at as usize].position();
        if k == 0 || k > SMALL_K {
            return self.knn(q, k, r2_max, filter, scratch);
        }
        scratch.found.clear();
        self.knn_bounded(q, k, r2_max, filter, &mut scratch.found, Start::Item(at))
    }

    /// Call `visit(item, d2, index)` for every item within sqrt(r2) of `q` (strictly).
    #[inline]
    pub fn within(&self, q: Vec3A, r2: f32, visit: &mut impl FnMut(&T, f32, u32)) {
        // Subtrees across a plane at exactly sqrt(r2) are visited too; none of their items
        // is strictly within.
        self.branch_and_bound(q, self.root(), r2, &mut |item, d2, i, _| {
            if d2 < r2 {
                visit(item, d2, i);
            }
        });
    }
}

/// Deeper than any tree of up to 2^32 items with LEAF-sized leaves.
const MAX_DEPTH: usize = 64;

/// The traversal stack, deep enough for any tree of up to 2^32 items.
type Stack<T> = crate::render::stack::Stack<T, MAX_DEPTH>;
