//! A static balanced kd-tree (Bentley 1975; as photon maps use it, Jensen 2001, section 6.3)
//! laid out for cache efficiency: the items are reordered in place into leaf buckets of at
//! most LEAF items, and the splitting planes live in a separate compact array in heap order
//! (node i has children 2i+1 and 2i+2), so the top of the tree shares a few cache lines
//! and a query touches item memory only in the leaves it scans. The items carry nothing for
//! the tree: a photon stays 28 bytes, plus 8 bytes of split per LEAF photons.
//!
//! k-nearest-neighbour queries gather every item within a guessed radius and select the k
//! nearest with `select_nth_unstable` (ties broken by index, so the answer never depends on
//! the guess); the guess is the previous query's radius on the same thread, which for the
//! spatially coherent queries of a render (pixels of a tile, photons in tree order) is
//! nearly right. This "radius-bounded gather" beats a heap-based search by several times
//! at k = 50-100.
//!
//! Chosen over kiddo after measuring both on photon maps (benches/kdtree.rs, recorded in
//! docs/performance.md).

use std::cmp::Ordering;
use std::mem::MaybeUninit;

use glam::Vec3A;

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

/// Nodes of at least this many items poll for cancellation (a few ms of work each).
const CANCEL_CHECK_MIN: usize = 64 * 1024;

/// Below this many items, subtrees are built on the calling thread.
const PARALLEL_BUILD_MIN: usize = 16 * 1024;

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
    /// Balance `items` into a tree. Deterministic: the result depends only on the input
    /// order, not on the thread count.
    pub fn build(items: Vec<T>) -> KdTree<T> {
        match Self::build_cancellable(items, &|| false) {
            Some(t) => t,
            None => unreachable!("never cancelled"),
        }
    }

    /// [`KdTree::build`] that polls `cancelled` at every large node and gives up (None) once
    /// it says so: balancing tens of millions of photons takes seconds.
    pub fn build_cancellable(
        items: Vec<T>,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Option<KdTree<T>> {
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        let mut keys: Vec<Key> = items
            .iter()
            .enumerate()
            .map(|(i, it)| {
                let p = it.position();
                (lo, hi) = (lo.min(p), hi.max(p));
                Key {
                    p: p.to_array(),
                    index: i as u32,
                }
            })
            .collect();
        let e = (hi - lo).max(Vec3A::ZERO);
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        let density_hint = if area > 0.0 && area.is_finite() {
            items.len() as f32 / area
        } else {
            f32::INFINITY
        };
        let mut nodes = Vec::new();
        balance(&mut keys, 0, &mut nodes, cancelled);
        if cancelled() {
            return None;
        }
        let items: Vec<T> = keys.iter().map(|k| items[k.index as usize]).collect();
        let len = nodes.iter().map(|n| n.0 + 1).max().unwrap_or(0);
        let mut splits = vec![Split::default(); len];
        for (i, s) in nodes {
            splits[i] = s;
        }
        Some(KdTree {
            items,
            splits,
            density_hint,
        })
    }

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
    /// makes: leaves are visited nearest first, and `scan(item, d2, index, bound)` sees each
    /// of their items and may lower `bound`; subtrees across a plane farther than
    /// sqrt(bound) are skipped (`>`: at exactly the bound, an item as near as the k-th but
    /// with a lower index may lie across the plane). Returns the final bound. Iterative, with
    /// the far children on a small stack: a recursive version measured 1.5x slower.
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
            for i in lo..hi {
                let item = &self.items[i as usize];
                let d2 = (item.position() - q).length_squared();
                scan(item, d2, i, &mut bound);
            }
        }
        bound
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

/// What balancing moves around: an item's position and index, 16 bytes (a photon is 28),
/// so that the selections move fewer bytes; the items are put in the final order once.
#[derive(Clone, Copy)]
struct Key {
    p: [f32; 3],
    index: u32,
}

impl KdItem for Key {
    #[inline]
    fn position(&self) -> Vec3A {
        Vec3A::from_array(self.p)
    }

    #[inline]
    fn coord(&self, axis: usize) -> f32 {
        self.p[axis]
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

/// Median split on the axis of largest extent of the node's items, recursively; large
/// halves in parallel. (Choosing the axis from the node's cell instead, which spares the
/// pass over the items, was measured: builds 4% faster, queries 25% slower.) Collects (node
/// index, split) pairs, scattered into the heap-ordered array afterwards.
///
/// Photons lie on planes: where more than half of a node's items share the median's
/// coordinate (a floor meeting a wall, split across the floor's height), the split would
/// leave some of them on each side, and every query on that plane would search both
/// halves. Such a split is replaced by one on the next longest axis where the median is
/// clear of ties (else the last one tried stays; k = 1 render on scene 1: precompute 18.4 -> 15.9 ms, camera
/// pass 98.7 -> 95.8 ms; build about 1 ms slower).
fn balance(
    items: &mut [Key],
    node: usize,
    out: &mut Vec<(usize, Split)>,
    cancelled: &(dyn Fn() -> bool + Sync),
) {
    if items.len() <= LEAF || (items.len() >= CANCEL_CHECK_MIN && cancelled()) {
        return;
    }
    let mut lo = Vec3A::splat(f32::INFINITY);
    let mut hi = Vec3A::splat(f32::NEG_INFINITY);
    for it in items.iter() {
        let p = it.position();
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let ext = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
    let mid = halves(0, items.len());
    let mut axis = axes[0];
    for (tried, &a) in axes.iter().enumerate() {
        axis = a;
        items.select_nth_unstable_by(mid, |x, y| x.coord(a).total_cmp(&y.coord(a)));
        let value = items[mid].coord(a);
        let degenerate = items[..mid].iter().any(|it| it.coord(a) == value);
        if !degenerate || tried == 2 || ext[axes[tried + 1]] <= 0.0 {
            break;
        }
    }
    out.push((
        node,
        Split {
            value: items[mid].coord(axis),
            axis: axis as u32,
        },
    ));
    let (left, right) = items.split_at_mut(mid);
    if left.len() >= PARALLEL_BUILD_MIN {
        let mut right_out = Vec::new();
        rayon::join(
            || balance(left, 2 * node + 1, out, cancelled),
            || balance(right, 2 * node + 2, &mut right_out, cancelled),
        );
        out.extend(right_out);
    } else {
        balance(left, 2 * node + 1, out, cancelled);
        balance(right, 2 * node + 2, out, cancelled);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream};

    #[derive(Clone, Copy, Debug)]
    struct P {
        p: Vec3A,
        id: u32,
    }
    impl KdItem for P {
        fn position(&self) -> Vec3A {
            self.p
        }
    }

    fn points(n: usize) -> Vec<P> {
        let mut s = Sampler::new(9, Stream::Camera, 0);
        (0..n)
            .map(|i| P {
                p: Vec3A::new(
                    s.next_f32(),
                    s.next_f32(),
                    (s.next_f32() * 4.0).floor() * 0.25,
                ),
                id: i as u32,
            })
            .collect()
    }

    #[test]
    fn knn_matches_brute_force_whatever_the_guess() {
        let pts = points(5000);
        let tree = KdTree::build(pts.clone());
        let mut scratch = KnnScratch::default();
        let mut s = Sampler::new(10, Stream::Camera, 0);
        for i in 0..300 {
            let q = Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32());
            let odd = |p: &P| p.id % 2 == 1;
            // Alternate wild guesses with the carried-over one.
            if i % 3 == 0 {
                scratch.r2_guess = [1e-9, 10.0, 0.0][i % 9 / 3];
            }
            // Both searches: branch and bound for small k, the gathered radius above.
            let k = [1, 2, 3, SMALL_K, SMALL_K + 1, 17][i % 6];
            let r2 = tree.knn(q, k, f32::INFINITY, &odd, &mut scratch);
            let mut got: Vec<u32> = scratch
                .found()
                .iter()
                .map(|f| tree.items()[f.1 as usize].id)
                .collect();
            got.sort();
            let mut all: Vec<(f32, u32)> = pts
                .iter()
                .filter(|p| odd(p))
                .map(|p| ((p.p - q).length_squared(), p.id))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut want: Vec<u32> = all[..k].iter().map(|x| x.1).collect();
            want.sort();
            assert_eq!(got, want, "k = {k}");
            assert_eq!(r2, all[k - 1].0);
            assert_eq!(scratch.found().last().unwrap().0, r2, "the k-th is last");
            let (n, d2) = tree.nearest(q, f32::INFINITY, &odd, None).unwrap();
            assert_eq!(tree.items()[n as usize].id, all[0].1);
            assert_eq!(d2, all[0].0);
            // Any hint gives the same answer.
            for hint in [0, 17, n, 4999] {
                assert_eq!(
                    tree.nearest(q, f32::INFINITY, &odd, Some(hint)),
                    Some((n, d2))
                );
            }
            let bound = all[16].0 * 1.0001;
            let mut count = 0;
            tree.within(q, bound, &mut |p, _, _| count += odd(p) as usize);
            assert_eq!(count, all.iter().filter(|a| a.0 < bound).count());
        }
    }

    /// On a lattice many photons lie at exactly the same distance: both searches must pick
    /// the same ones (the lowest indices), as a brute-force ranking does.
    #[test]
    fn knn_breaks_ties_by_index_in_both_searches() {
        let lattice: Vec<P> = (0..1000)
            .map(|i| P {
                p: Vec3A::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32),
                id: i as u32,
            })
            .collect();
        let tree = KdTree::build(lattice);
        let mut scratch = KnnScratch::default();
        for (j, k) in [1, 2, 5, SMALL_K, SMALL_K + 1, 30].into_iter().enumerate() {
            for q in [Vec3A::new(4.0, 4.0, 4.0), Vec3A::new(4.5, 4.5, 4.0)] {
                for r2_max in [f32::INFINITY, 1.0, 0.5 + j as f32 * 0.25] {
                    let r2 = tree.knn(q, k, r2_max, &|_| true, &mut scratch);
                    let mut got = scratch.found().to_vec();
                    got.sort_by(by_distance_then_index);
                    let mut all: Vec<(f32, u32)> = tree
                        .items()
                        .iter()
                        .enumerate()
                        .map(|(i, p)| ((p.p - q).length_squared(), i as u32))
                        .filter(|a| a.0 < r2_max)
                        .collect();
                    all.sort_by(by_distance_then_index);
                    all.truncate(k);
                    assert_eq!(got, all, "k = {k}, q = {q}, r2_max = {r2_max}");
                    let want_r2 = if all.len() == k { all[k - 1].0 } else { r2_max };
                    assert_eq!(r2, want_r2);
                }
            }
        }
    }

    #[test]
    fn build_is_deterministic_across_thread_counts() {
        let pts = points(100_000);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let a = one.install(|| KdTree::build(pts.clone()));
        let b = two.install(|| KdTree::build(pts.clone()));
        let ids = |t: &KdTree<P>| t.items().iter().map(|p| p.id).collect::<Vec<_>>();
        let splits = |t: &KdTree<P>| {
            t.splits
                .iter()
                .map(|s| (s.value, s.axis))
                .collect::<Vec<_>>()
        };
        assert_eq!(ids(&a), ids(&b));
        assert_eq!(splits(&a), splits(&b));
    }

    #[test]
    fn radius_bound_limits_results() {
        let tree = KdTree::build(points(2000));
        let mut scratch = KnnScratch::default();
        let r2 = tree.knn(Vec3A::new(5.0, 5.0, 5.0), 10, 0.01, &|_| true, &mut scratch);
        assert!(scratch.found().is_empty());
        assert_eq!(r2, 0.01);
        let tiny = KdTree::build(points(5));
        let r2 = tiny.knn(Vec3A::ZERO, 10, 100.0, &|_| true, &mut scratch);
        assert_eq!((scratch.found().len(), r2), (5, 100.0));
    }
}
