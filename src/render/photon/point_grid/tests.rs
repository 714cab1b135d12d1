//! The grid's searches against brute force and against the kd-tree.

use glam::Vec3A;

use super::{BoxLimits, PointGrid};

/// At most 8 cells; points without limit.
const LIMITS: BoxLimits = BoxLimits {
    cells: 8,
    points: usize::MAX,
};
use crate::render::photon::kdtree::by_distance_then_index;
use crate::render::photon::test_points::{P, lattice, on_planes};
use crate::render::photon::{KdTree, KnnScratch};
use crate::render::sampling::{Sampler, Stream};

/// Points on four planes (as photons lie on walls), and one in 50 lifted off them.
fn points(n: usize, seed: u64) -> Vec<P> {
    let mut s = Sampler::new(seed, Stream::Camera, 1);
    let mut pts = on_planes(n, seed);
    for p in pts.iter_mut().step_by(50) {
        p.p.z = s.next_f32();
    }
    pts
}

/// The nearest point passing `filter` within the bound, ties to the lowest grid index.
fn brute_nearest(
    grid: &PointGrid<P>,
    q: Vec3A,
    r2_max: f32,
    filter: impl Fn(&P) -> bool,
) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for (i, p) in grid.points.iter().enumerate() {
        let d2 = (p.p - q).length_squared();
        if d2 < r2_max && filter(p) && best.is_none_or(|b| d2 < b.1) {
            best = Some((i as u32, d2));
        }
    }
    best
}

#[test]
fn nearest_matches_brute_force_whatever_the_hint() {
    let pts = points(3000, 1);
    let grid = &PointGrid::build(&pts, None).unwrap();
    // The order says where each grid point came from.
    for (i, &o) in grid.order().iter().enumerate() {
        assert_eq!(grid.points[i].id, pts[o as usize].id);
    }
    let mut s = Sampler::new(2, Stream::Camera, 0);
    let mut last = None;
    let mut with_answer = 0;
    let mut q = Vec3A::new(0.5, 0.5, 0.25);
    for i in 0..2000 {
        // Queries wander like a camera's: small steps on a plane of points, sometimes a
        // jump anywhere (outside the points' box too).
        let step = Vec3A::new(s.next_f32() - 0.5, s.next_f32() - 0.5, 0.0) * 0.02;
        q = if i % 7 == 0 {
            Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32()) * 1.2 - 0.1
        } else {
            (q + step) * Vec3A::new(1.0, 1.0, 0.0) + Vec3A::Z * 0.25
        };
        let most = |p: &P| !p.id.is_multiple_of(3);
        let r2_max = [f32::INFINITY, 0.01, 1e-4, 0.3, 0.0, f32::NAN][i % 6];
        let want = brute_nearest(grid, q, r2_max, most);
        let hints = [
            None,
            last,
            Some(0),
            Some(2999),
            want.map(|w| w.0),
            Some(1_000_000),
        ];
        for hint in hints {
            assert_eq!(
                grid.nearest(q, r2_max, &most, hint),
                want,
                "q = {q}, hint = {hint:?}"
            );
        }
        with_answer += want.is_some() as usize;
        last = want.map(|w| w.0).or(last);
    }
    assert!(
        with_answer > 800,
        "most queries with a bound find a point ({with_answer})"
    );
}

/// On a lattice many points lie at exactly the same distance: the lowest index wins. With
/// cells one lattice step wide (and offset far from the origin, where rounding is coarse),
/// the tied points lie in different cells, exactly at the bound's distance.
#[test]
fn nearest_breaks_ties_by_index() {
    let cases = [
        (0.0, None),
        (0.0, Some(1.0)),
        (1e6, Some(1.0)),
        (0.0, Some(0.5)),
    ];
    for (offset, cell) in cases {
        let grid = PointGrid::build(&lattice(offset), cell).unwrap();
        for q in [
            Vec3A::new(4.5, 4.5, 4.0),
            Vec3A::new(4.5, 4.5, 4.5),
            Vec3A::new(0.5, 9.5, 9.5),
            Vec3A::new(-3.0, 4.5, 4.5),
            Vec3A::new(5.0, 5.0, 5.0),
        ] {
            let q = q + Vec3A::splat(offset);
            let want = brute_nearest(&grid, q, f32::INFINITY, |_| true);
            for hint in [None, Some(0), Some(999), want.map(|w| w.0)] {
                let got = grid.nearest(q, f32::INFINITY, &|_| true, hint);
                assert_eq!(got, want, "offset {offset}, cell {cell:?}, q = {q}");
            }
        }
    }
}

/// Built from a tree's items, the grid's k-NN is the tree's, ties included; a box over
/// the limits declines.
#[test]
fn knn_matches_the_tree() {
    let tree = KdTree::build(points(4000, 3));
    let r_max = 0.03;
    let grid = &PointGrid::build(tree.items(), Some(2.0 * r_max)).unwrap();
    let mut s = Sampler::new(4, Stream::Camera, 0);
    let (mut tree_scratch, mut found) = (KnnScratch::default(), Vec::new());
    let mut answered = 0;
    for i in 0..3000 {
        let (x, y) = (s.next_f32(), s.next_f32());
        let q = Vec3A::new(x, y, (s.next_f32() * 4.0).floor() * 0.25);
        let k = 1 + i % 8;
        let r2_max = [r_max * r_max, 1e-4, 0.0][i / 8 % 3];
        let even = |p: &P| p.id.is_multiple_of(2);
        let Some(r2) = grid.knn(q, k, r2_max, LIMITS, &even, &mut found) else {
            assert!(found.is_empty());
            continue;
        };
        answered += 1;
        let want_r2 = tree.knn(q, k, r2_max, &even, &mut tree_scratch);
        let mut want = tree_scratch.found().to_vec();
        want.sort_by(by_distance_then_index);
        assert_eq!(found, want, "q = {q}, k = {k}");
        assert_eq!(r2, want_r2);
    }
    assert!(
        answered > 2500,
        "most boxes meet at most 8 cells ({answered})"
    );
    // A bound wider than the cells: the box meets too many; no bound at all: the same.
    let all = |_: &P| true;
    for r2_max in [1.0, f32::INFINITY] {
        let got = grid.knn(Vec3A::splat(0.5), 2, r2_max, LIMITS, &all, &mut found);
        assert_eq!(got, None);
    }
    // A box holding more points than allowed declines too, one holding none answers.
    let none = BoxLimits {
        cells: 8,
        points: 0,
    };
    let (on_a_plane, between) = (Vec3A::new(0.5, 0.5, 0.25), Vec3A::new(0.5, 0.5, 0.125));
    let got = grid.knn(on_a_plane, 2, r_max * r_max, none, &all, &mut found);
    assert_eq!(got, None);
    let got = grid.knn(between, 2, 1e-4, none, &all, &mut found);
    assert_eq!((got, found.len()), (Some(1e-4), 0));
    // k = 0: nothing, and the bound.
    let got = grid.knn(Vec3A::splat(0.5), 0, 1e-4, LIMITS, &all, &mut found);
    assert_eq!((got, found.len()), (Some(1e-4), 0));
}

#[test]
fn degenerate_sets_still_answer() {
    // One point; all points at one place; all on a plane; all on a line; a set with points
    // at non-finite positions (left out).
    let one = [P {
        p: Vec3A::ONE,
        id: 0,
    }];
    let same = vec![
        P {
            p: Vec3A::splat(2.0),
            id: 0
        };
        40
    ];
    let squash = |m: Vec3A| {
        let pts = points(500, 5).into_iter();
        pts.map(|p| P { p: p.p * m, ..p }).collect::<Vec<_>>()
    };
    let (flat, line) = (squash(Vec3A::new(1.0, 1.0, 0.0)), squash(Vec3A::X));
    let mut holes = points(300, 6);
    holes[3].p = Vec3A::new(f32::NAN, 0.0, 0.0);
    holes[7].p = Vec3A::new(0.5, f32::INFINITY, 0.5);
    for set in [&one[..], &same[..], &flat[..], &line[..], &holes[..]] {
        // Automatic cells, tiny ones (the grid's size caps them) and huge ones.
        for cell in [None, Some(1e-30), Some(1e30)] {
            let grid = &PointGrid::build(set, cell).unwrap();
            let finite = set.iter().filter(|p| p.p.is_finite()).count();
            assert_eq!((grid.points.len(), grid.order().len()), (finite, finite));
            for q in [
                Vec3A::ZERO,
                Vec3A::splat(2.0),
                Vec3A::new(0.3, 0.7, 0.0),
                Vec3A::NAN,
            ] {
                let want = brute_nearest(grid, q, f32::INFINITY, |_| true);
                let got = grid.nearest(q, f32::INFINITY, &|_| true, None);
                assert_eq!(got, want, "q = {q}, cell {cell:?}");
            }
        }
    }
    assert!(PointGrid::<P>::build(&[], None).is_none());
    let nowhere = [P {
        p: Vec3A::NAN,
        id: 0,
    }];
    assert!(PointGrid::build(&nowhere, None).is_none());
}
