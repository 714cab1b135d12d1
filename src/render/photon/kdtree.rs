//! A static, implicit, balanced kd-tree (Jensen 2001, "Realistic Image Synthesis Using
//! Photon Mapping", section 6.3): the items are reordered in place so that each range's
//! median is its node, split on the axis of largest extent, with the axis kept in two bits
//! of the item. No pointers and no second copy of the positions: the tree costs nothing
//! beyond the items themselves, which is what keeps a photon at 32 bytes.
//!
//! Chosen over kiddo after measuring both on photon-like data (benches/kdtree.rs, recorded in
//! docs/performance.md): building is 3-4x faster and k-NN queries with a per-item filter
//! (needed to skip photons on the other side of a thin wall) are faster as well.

use glam::Vec3A;

/// An item the tree can hold.
pub trait KdItem: Copy + Send + Sync {
    fn position(&self) -> Vec3A;
    fn axis(&self) -> usize;
    fn set_axis(&mut self, axis: usize);
}

/// Below this many items, subtrees are built on the calling thread.
const PARALLEL_BUILD_MIN: usize = 16 * 1024;

pub struct KdTree<T: KdItem> {
    items: Vec<T>,
}

/// Bounded max-heap of the k best (squared distance, index) pairs seen so far
/// (Jensen's `locate_photons`); reused between queries to avoid allocation.
#[derive(Default)]
pub struct KnnHeap {
    entries: Vec<(f32, u32)>,
}

impl KnnHeap {
    pub fn indices(&self) -> impl Iterator<Item = u32> + '_ {
        self.entries.iter().map(|e| e.1)
    }

    /// (squared distance, index) pairs; once the heap is full, the first is the farthest.
    pub fn entries(&self) -> &[(f32, u32)] {
        &self.entries
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn sift_down(&mut self, mut i: usize) {
        let h = &mut self.entries;
        let n = h.len();
        loop {
            let l = 2 * i + 1;
            if l >= n {
                break;
            }
            let c = if l + 1 < n && h[l + 1].0 > h[l].0 {
                l + 1
            } else {
                l
            };
            if h[c].0 > h[i].0 {
                h.swap(c, i);
                i = c;
            } else {
                break;
            }
        }
    }

    /// Offer a candidate; returns the new search radius^2 once the heap holds k items.
    #[inline]
    fn offer(&mut self, d2: f32, idx: u32, k: usize, r2: &mut f32) {
        if self.entries.len() < k {
            self.entries.push((d2, idx));
            if self.entries.len() == k {
                for i in (0..k / 2).rev() {
                    self.sift_down(i);
                }
                *r2 = self.entries[0].0;
            }
        } else {
            self.entries[0] = (d2, idx);
            self.sift_down(0);
            *r2 = self.entries[0].0;
        }
    }
}

impl<T: KdItem> KdTree<T> {
    /// Balance `items` into a tree. Deterministic: the result depends only on the input
    /// order, not on the thread count.
    pub fn build(mut items: Vec<T>) -> KdTree<T> {
        balance(&mut items);
        KdTree { items }
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

    /// The (at most) k nearest items within sqrt(r2_max) of `q` that pass `filter`, into
    /// `heap`. Returns the squared radius of the search: the k-th distance if k were found,
    /// else `r2_max`.
    pub fn knn(
        &self,
        q: Vec3A,
        k: usize,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
        heap: &mut KnnHeap,
    ) -> f32 {
        heap.entries.clear();
        let mut r2 = r2_max;
        if k > 0 {
            self.knn_node(0, self.items.len(), q, k, filter, heap, &mut r2);
        }
        if heap.entries.len() == k {
            heap.entries[0].0
        } else {
            r2_max
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn knn_node(
        &self,
        lo: usize,
        hi: usize,
        q: Vec3A,
        k: usize,
        filter: &impl Fn(&T) -> bool,
        heap: &mut KnnHeap,
        r2: &mut f32,
    ) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let item = &self.items[mid];
        let p = item.position();
        if hi - lo > 1 {
            let axis = item.axis();
            let d = q[axis] - p[axis];
            if d < 0.0 {
                self.knn_node(lo, mid, q, k, filter, heap, r2);
                if d * d < *r2 {
                    self.knn_node(mid + 1, hi, q, k, filter, heap, r2);
                }
            } else {
                self.knn_node(mid + 1, hi, q, k, filter, heap, r2);
                if d * d < *r2 {
                    self.knn_node(lo, mid, q, k, filter, heap, r2);
                }
            }
        }
        let d2 = (p - q).length_squared();
        if d2 < *r2 && filter(item) {
            heap.offer(d2, mid as u32, k, r2);
        }
    }

    /// Call `visit(item, d2)` for every item within sqrt(r2) of `q`.
    pub fn within(&self, q: Vec3A, r2: f32, visit: &mut impl FnMut(&T, f32)) {
        self.within_node(0, self.items.len(), q, r2, visit);
    }

    fn within_node(
        &self,
        lo: usize,
        hi: usize,
        q: Vec3A,
        r2: f32,
        visit: &mut impl FnMut(&T, f32),
    ) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let item = &self.items[mid];
        let p = item.position();
        if hi - lo > 1 {
            let axis = item.axis();
            let d = q[axis] - p[axis];
            if d < 0.0 || d * d < r2 {
                self.within_node(lo, mid, q, r2, visit);
            }
            if d >= 0.0 || d * d < r2 {
                self.within_node(mid + 1, hi, q, r2, visit);
            }
        }
        let d2 = (p - q).length_squared();
        if d2 < r2 {
            visit(item, d2);
        }
    }

    /// The nearest item passing `filter` within sqrt(r2_max), with its squared distance.
    pub fn nearest(
        &self,
        q: Vec3A,
        r2_max: f32,
        filter: &impl Fn(&T) -> bool,
    ) -> Option<(&T, f32)> {
        let mut best: Option<(usize, f32)> = None;
        let mut r2 = r2_max;
        self.nearest_node(0, self.items.len(), q, filter, &mut best, &mut r2);
        best.map(|(i, d2)| (&self.items[i], d2))
    }

    fn nearest_node(
        &self,
        lo: usize,
        hi: usize,
        q: Vec3A,
        filter: &impl Fn(&T) -> bool,
        best: &mut Option<(usize, f32)>,
        r2: &mut f32,
    ) {
        if lo >= hi {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let item = &self.items[mid];
        let p = item.position();
        let d2 = (p - q).length_squared();
        if d2 < *r2 && filter(item) {
            *best = Some((mid, d2));
            *r2 = d2;
        }
        if hi - lo > 1 {
            let axis = item.axis();
            let d = q[axis] - p[axis];
            let (near, far) = if d < 0.0 {
                ((lo, mid), (mid + 1, hi))
            } else {
                ((mid + 1, hi), (lo, mid))
            };
            self.nearest_node(near.0, near.1, q, filter, best, r2);
            if d * d < *r2 {
                self.nearest_node(far.0, far.1, q, filter, best, r2);
            }
        }
    }
}

/// Median split on the axis of largest extent, recursively; large halves in parallel.
fn balance<T: KdItem>(items: &mut [T]) {
    if items.len() <= 1 {
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
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        a.position()[axis].total_cmp(&b.position()[axis])
    });
    items[mid].set_axis(axis);
    let (left, right) = items.split_at_mut(mid);
    let right = &mut right[1..];
    if left.len() >= PARALLEL_BUILD_MIN {
        rayon::join(|| balance(left), || balance(right));
    } else {
        balance(left);
        balance(right);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream};

    #[derive(Clone, Copy, Debug)]
    struct P {
        p: Vec3A,
        axis: u8,
        id: u32,
    }
    impl KdItem for P {
        fn position(&self) -> Vec3A {
            self.p
        }
        fn axis(&self) -> usize {
            self.axis as usize
        }
        fn set_axis(&mut self, axis: usize) {
            self.axis = axis as u8;
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
                axis: 0,
                id: i as u32,
            })
            .collect()
    }

    #[test]
    fn knn_matches_brute_force() {
        let pts = points(5000);
        let tree = KdTree::build(pts.clone());
        let mut heap = KnnHeap::default();
        let mut s = Sampler::new(10, Stream::Camera, 0);
        for _ in 0..200 {
            let q = Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32());
            let odd = |p: &P| p.id % 2 == 1;
            let r2 = tree.knn(q, 17, f32::INFINITY, &odd, &mut heap);
            let mut got: Vec<u32> = heap
                .indices()
                .map(|i| tree.items()[i as usize].id)
                .collect();
            got.sort();
            let mut all: Vec<(f32, u32)> = pts
                .iter()
                .filter(|p| odd(p))
                .map(|p| ((p.p - q).length_squared(), p.id))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut want: Vec<u32> = all[..17].iter().map(|x| x.1).collect();
            want.sort();
            assert_eq!(got, want);
            assert_eq!(r2, all[16].0);
            let (n, d2) = tree.nearest(q, f32::INFINITY, &odd).unwrap();
            assert_eq!(n.id, all[0].1);
            assert_eq!(d2, all[0].0);
            let mut count = 0;
            tree.within(q, all[16].0 * 1.0001, &mut |p, _| count += odd(p) as usize);
            assert_eq!(count, 17);
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
        let ids = |t: &KdTree<P>| t.items().iter().map(|p| (p.id, p.axis)).collect::<Vec<_>>();
        assert_eq!(ids(&a), ids(&b));
    }

    #[test]
    fn radius_bound_limits_results() {
        let tree = KdTree::build(points(2000));
        let mut heap = KnnHeap::default();
        let r2 = tree.knn(Vec3A::new(5.0, 5.0, 5.0), 10, 0.01, &|_| true, &mut heap);
        assert!(heap.is_empty());
        assert_eq!(r2, 0.01);
    }
}
