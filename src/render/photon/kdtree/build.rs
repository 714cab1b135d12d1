//! Balancing a kd-tree: median splits into leaf buckets, the splits in heap order.

use glam::Vec3A;
use rayon::prelude::*;

use super::{KdItem, KdTree, LEAF, Split, halves};

/// Nodes of at least this many items poll for cancellation (a few ms of work each).
const CANCEL_CHECK_MIN: usize = 64 * 1024;

/// Below this many items, subtrees are built on the calling thread. While the global tree
/// is balanced the other thread traces the caustic photons; once done, it can only help
/// with subtrees split off at this size or above, so 4k rather than 16k lets it help sooner
/// (measured: docs/performance-history.md, "size of the subtrees split off").
const PARALLEL_BUILD_MIN: usize = 4 * 1024;

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
        let mut keys: Vec<Key> = items
            .iter()
            .enumerate()
            .map(|(i, it)| Key {
                p: it.position().to_array(),
                index: i as u32,
            })
            .collect();
        let (lo, hi) = bounds(&keys);
        let e = (hi - lo).max(Vec3A::ZERO);
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        let density_hint = if area > 0.0 && area.is_finite() {
            items.len() as f32 / area
        } else {
            f32::INFINITY
        };
        let mut nodes = Vec::new();
        balance(&mut keys, (lo, hi), 0, &mut nodes, cancelled);
        if cancelled() {
            return None;
        }
        // The photons in tree order: a gather from all over the input, on the critical path
        // after the last selection, so in parallel (measured: docs/performance-history.md,
        // "gather in tree order in parallel"). Small trees stay on the calling thread.
        let items: Vec<T> = keys
            .par_iter()
            .with_min_len(PARALLEL_BUILD_MIN)
            .map(|k| items[k.index as usize])
            .collect();
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

/// The bounding box of `keys`' positions.
fn bounds(keys: &[Key]) -> (Vec3A, Vec3A) {
    let mut lo = Vec3A::splat(f32::INFINITY);
    let mut hi = Vec3A::splat(f32::NEG_INFINITY);
    for k in keys {
        (lo, hi) = (lo.min(k.position()), hi.max(k.position()));
    }
    (lo, hi)
}

/// Median split on the axis of largest extent of the node's items, whose box the caller
/// passes (the build has the root's from its first pass), recursively; large halves in
/// parallel. (Choosing the axis from the node's cell instead, which spares the pass over
/// the items, builds a little faster and makes queries much slower; measured:
/// docs/performance-history.md, "split axis from the items".) Collects (node index, split)
/// pairs, scattered into the heap-ordered array afterwards.
///
/// Photons lie on planes: where more than half of a node's items share the median's
/// coordinate (a floor meeting a wall, split across the floor's height), the split would
/// leave some of them on each side, and every query on that plane would search both
/// halves. Such a split is replaced by one on the next longest axis where the median is
/// clear of ties (else the last one tried stays): the k = 1 render is faster for a slightly
/// slower build (measured: docs/performance-history.md, "splits clear of ties").
fn balance(
    items: &mut [Key],
    (lo, hi): (Vec3A, Vec3A),
    node: usize,
    out: &mut Vec<(usize, Split)>,
    cancelled: &(dyn Fn() -> bool + Sync),
) {
    if items.len() <= LEAF || (items.len() >= CANCEL_CHECK_MIN && cancelled()) {
        return;
    }
    let ext = hi - lo;
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
    let mid = halves(0, items.len());
    let mut axis = axes[0];
    let mut left_box = (lo, hi);
    for (tried, &a) in axes.iter().enumerate() {
        axis = a;
        select_median(items, mid, a);
        let value = items[mid].coord(a);
        // The left half's box, which its own split needs, also tells the ties: its items
        // are all <= the median, so one equals it exactly when their maximum does.
        left_box = bounds(&items[..mid]);
        let degenerate = left_box.1[a] == value;
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
            || balance(left, left_box, 2 * node + 1, out, cancelled),
            || balance_half(right, 2 * node + 2, &mut right_out, cancelled),
        );
        out.extend(right_out);
    } else {
        balance(left, left_box, 2 * node + 1, out, cancelled);
        balance_half(right, 2 * node + 2, out, cancelled);
    }
}

/// Moves the median of `items` on `axis` to `mid`, smaller (by `total_cmp`) before it and
/// larger after. One instance per axis, so that the comparison reads a fixed field rather
/// than an index checked on every call (measured, together with the left box doubling as
/// the tie check: docs/performance-history.md, "median selection per axis").
fn select_median(items: &mut [Key], mid: usize, axis: usize) {
    fn on<const A: usize>(items: &mut [Key], mid: usize) {
        items.select_nth_unstable_by(mid, |x, y| x.p[A].total_cmp(&y.p[A]));
    }
    match axis {
        0 => on::<0>(items, mid),
        1 => on::<1>(items, mid),
        _ => on::<2>(items, mid),
    }
}

/// [`balance`] on the right half of a node, with the half's box (a leaf needs none).
fn balance_half(
    items: &mut [Key],
    node: usize,
    out: &mut Vec<(usize, Split)>,
    cancelled: &(dyn Fn() -> bool + Sync),
) {
    if items.len() > LEAF {
        balance(items, bounds(items), node, out, cancelled);
    }
}
