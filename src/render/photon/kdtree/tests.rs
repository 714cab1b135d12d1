//! The kd-tree's searches against brute force, and its build's determinism.

use glam::Vec4;

use super::lanes::{distances4, within4};
use super::*;
use crate::render::photon::test_points::{P, lattice, on_planes};
use crate::render::sampling::{Sampler, Stream};

fn points(n: usize) -> Vec<P> {
    on_planes(n, 9)
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
    let tree = KdTree::build(lattice(0.0));
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

/// A search from an item's own leaf upward finds what a search from the root finds.
#[test]
fn knn_at_an_item_equals_knn_at_its_position() {
    let pts = points(6000);
    let tree = KdTree::build(pts);
    let ties = KdTree::build(lattice(0.0));
    let (mut a, mut b) = (KnnScratch::default(), KnnScratch::default());
    for t in [&tree, &ties] {
        for i in (0..t.len() as u32).step_by(7) {
            // Every k of the small-k search with every bound (none, a few photons', a
            // lattice step's), and one k above it.
            let k = [1, 2, 3, 5, SMALL_K, SMALL_K + 3][i as usize % 6];
            let r2_max = [f32::INFINITY, 1e-3, 2.0][i as usize / 6 % 3];
            let odd = |p: &P| p.id % 2 == 1;
            let q = t.items()[i as usize].position();
            let want = t.knn(q, k, r2_max, &odd, &mut a);
            let got = t.knn_at(i, k, r2_max, &odd, &mut b);
            let sorted = |s: &KnnScratch| {
                let mut v = s.found().to_vec();
                v.sort_by(by_distance_then_index);
                v
            };
            assert_eq!((got, sorted(&b)), (want, sorted(&a)), "item {i}, k = {k}");
        }
    }
}

/// The leaf scan's four-at-a-time distances are the scalar ones bit for bit, so that a
/// search's answer (ties included) is what one item at a time would give.
#[test]
fn four_distances_equal_the_scalar_ones() {
    let mut pts = points(4000);
    // Large, tiny and infinite coordinates too.
    pts[0].p = Vec3A::new(3e18, -1e-30, 3.0);
    pts[1].p = Vec3A::new(f32::INFINITY, 0.0, 1.0);
    pts[2].p = Vec3A::new(-7e17, 2e18, f32::MIN_POSITIVE);
    pts[3].p = Vec3A::new(1e-20, 7e-21, -3e-20);
    let mut s = Sampler::new(12, Stream::Camera, 0);
    let (fours, _) = pts.as_chunks::<4>();
    for four in fours {
        let q = Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32()) * 3.0 - 1.0;
        let want = [0, 1, 2, 3].map(|j| (four[j].p - q).length_squared().to_bits());
        assert_eq!(distances4(q, four).to_array().map(f32::to_bits), want);
    }
    let d2 = Vec4::new(0.5, 1.0, f32::NAN, 2.0);
    assert_eq!(within4(d2, 1.0), 0b0011);
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
