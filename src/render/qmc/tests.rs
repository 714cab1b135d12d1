use super::*;

/// Asserts that `points` fall one in each of `points.len()` equal strips of [0, 1), in
/// each coordinate.
fn assert_one_per_strip(points: &[[f32; 2]], what: &str) {
    let n = points.len();
    for axis in 0..2 {
        let mut strips = vec![0u32; n];
        for p in points {
            strips[(p[axis] * n as f32) as usize] += 1;
        }
        assert!(
            strips.iter().all(|&c| c == 1),
            "{what}: coordinate {axis} not stratified: {strips:?}"
        );
    }
}

/// The first 2^k points of a pixel's 2D projection fall one per cell of a 2^k grid of
/// equal strips (a (0,2)-sequence after scrambling): the property the integrators rely
/// on, and independent samples lack.
#[test]
fn each_pair_is_stratified_across_iterations() {
    for pair in 0..6 {
        let points: Vec<_> = (0..256)
            .map(|i| {
                let mut s = SobolStream::new(5, Stream::Camera, 77, i);
                for _ in 0..pair {
                    s.next_2d();
                }
                s.next_2d()
            })
            .collect();
        assert_one_per_strip(&points, &format!("pair {pair}"));
    }
}

/// The branches of a sequence's first points are one stratified set: 4 points with 8
/// branches each give 32 first pairs, one in each of 32 equal strips in x and in y
/// (a pixel's gather directions over its samples).
#[test]
fn branches_of_a_sequence_s_points_are_stratified_together() {
    let streams = |j| SobolStream::new(5, Stream::Camera, 77, j);
    assert_one_per_strip(&gathers(streams, 4, 8), "branches");
}

/// The first pair of `branches` branches of each of the first `points` points of the
/// streams `stream(j)`, after each point's own first pair (which does not move them).
fn gathers(stream: impl Fn(u64) -> SobolStream, points: u64, branches: u32) -> Vec<[f32; 2]> {
    let mut out = Vec::new();
    for j in 0..points {
        let mut s = stream(j);
        s.next_2d();
        out.extend((0..branches).map(|k| s.branch(Branch::Gather, k, branches).next_2d()));
    }
    out
}

/// The tables give the crate's points, bit for bit.
#[test]
fn first_four_is_the_crates_sample_4d() {
    for k in 0..20_000u32 {
        let index = k.wrapping_mul(2_654_435_761) >> 16;
        let seed = splitmix64(k as u64) as u32;
        assert_eq!(
            first_four(index, seed),
            sobol_burley::sample_4d(index, 0, seed)
        );
    }
}

/// Different pixels, streams and blocks get different sequences; the same arguments
/// the same numbers.
#[test]
fn sequences_are_reproducible_and_distinct() {
    let draw = |seed, stream, index, n| {
        let mut s = SobolStream::new(seed, stream, index, n);
        (0..9).map(|_| s.next_f32()).collect::<Vec<_>>()
    };
    let a = draw(1, Stream::Camera, 3, 10);
    assert_eq!(a, draw(1, Stream::Camera, 3, 10));
    assert_ne!(a, draw(1, Stream::Camera, 4, 10));
    assert_ne!(a, draw(1, Stream::LightPaths, 3, 10));
    assert_ne!(a, draw(2, Stream::Camera, 3, 10));
    assert_ne!(a, draw(1, Stream::Camera, 3, 10 + BLOCK));
    assert!(a.iter().all(|x| (0.0..1.0).contains(x)));
}

/// The mean of many sequences' coordinates is 1/2 in every dimension (no dimension is
/// biased by the padding).
#[test]
fn coordinates_are_uniform_on_average() {
    let dims = 12;
    let mut sum = vec![0.0f64; dims];
    let count = 4096;
    for p in 0..count {
        let mut s = SobolStream::new(9, Stream::Camera, p, p % 7);
        for d in sum.iter_mut() {
            *d += s.next_f32() as f64;
        }
    }
    for (d, v) in sum.iter().enumerate() {
        let mean = v / count as f64;
        assert!((mean - 0.5).abs() < 0.015, "dimension {d}: mean {mean}");
    }
}

/// The branches of one iteration over a tile of 16 x 16 pixels: one per cell of a 16 x 16
/// grid and one per strip of 256 in each coordinate, for every branch (with independent
/// pixels, about 94 of the 256 cells would be empty).
#[test]
fn a_tile_s_branches_are_stratified_together() {
    let side = TILE_SIDE;
    let n = (side * side) as usize;
    for (k, count) in [(0, 1), (3, 8)] {
        let mut points = Vec::new();
        for y in 3 * side..4 * side {
            for x in side..2 * side {
                let pixel = y as u64 * 1000 + x as u64;
                let s = SobolStream::interleaved(5, Stream::Camera, pixel, [x, y], 7);
                points.push(s.branch(Branch::Gather, k, count).next_2d());
            }
        }
        assert_one_per_strip(&points, &format!("branch {k}"));
        let mut cells = vec![0u32; n];
        for [u, v] in &points {
            let (i, j) = ((u * side as f32) as usize, (v * side as f32) as usize);
            cells[i * side as usize + j] += 1;
        }
        assert!(cells.iter().all(|&c| c == 1), "branch {k}: cells {cells:?}");
    }
}

/// A pixel's interleaved branches over its samples are still one stratified set, as in
/// [`branches_of_a_sequence_s_points_are_stratified_together`], at scales finer than the
/// shifts' grid too (512 points); the sample's own draws are those of its own sequence.
#[test]
fn an_interleaved_pixel_s_branches_stay_stratified() {
    for xy in [[0, 0], [5, 9], [37, 250]] {
        let streams = |j| SobolStream::interleaved(5, Stream::Camera, 77, xy, j);
        assert_one_per_strip(&gathers(streams, 128, 4), &format!("{xy:?}"));
        let mut own = SobolStream::new(5, Stream::Camera, 77, 3);
        let mut interleaved = SobolStream::interleaved(5, Stream::Camera, 77, xy, 3);
        for _ in 0..9 {
            assert_eq!(own.next_f32(), interleaved.next_f32());
        }
    }
}

/// Every aligned 4 x 4 square of a tile holds a 16-point net of its own (the slots run
/// along the Z-order curve): one of its branches in each of 16 strips of each coordinate.
#[test]
fn every_aligned_square_of_a_tile_is_stratified() {
    for (x0, y0) in [(0, 0), (4, 8), (12, 12)] {
        let mut points = Vec::new();
        for y in y0..y0 + 4 {
            for x in x0..x0 + 4 {
                let s = SobolStream::interleaved(2, Stream::Camera, (y * 64 + x) as u64, [x, y], 5);
                points.push(s.branch(Branch::Gather, 1, 4).next_2d());
            }
        }
        assert_one_per_strip(&points, &format!("square at {x0}, {y0}"));
    }
}

/// Two pixels of a tile, once each has a point in every strip of the shifts' grid, do not
/// hold the same offsets within the strips in another order (an XOR shift alone only
/// swaps whole strips; the bits below it are scrambled for each pixel), and their
/// branches' later draws differ.
#[test]
fn interleaved_pixels_differ_within_the_shifts_grid() {
    let n = 1usize << SLOT_BITS;
    let draws = |xy: [u32; 2]| {
        let (mut offsets, mut later) = (Vec::new(), Vec::new());
        for j in 0..n as u64 {
            let pixel = xy[1] as u64 * 256 + xy[0] as u64;
            let mut b = SobolStream::interleaved(3, Stream::Camera, pixel, xy, j).branch(
                Branch::Gather,
                0,
                1,
            );
            let [x, _] = b.next_2d();
            offsets.push((x * 16_777_216.0) as u32 & ((1 << (24 - SLOT_BITS)) - 1));
            b.next_2d();
            later.push(b.next_f32());
        }
        offsets.sort_unstable();
        (offsets, later)
    };
    let (a, a_later) = draws([2, 3]);
    let (b, b_later) = draws([7, 1]);
    let same = a.iter().zip(&b).filter(|(p, q)| p == q).count();
    assert!(
        same < n / 16,
        "{same} of {n} offsets within strips are the same"
    );
    let same_later = a_later.iter().zip(&b_later).filter(|(p, q)| p == q).count();
    assert!(same_later < n / 16, "{same_later} later draws are the same");
}

/// Interleaved branches are uniform on average over seeds in each of their first
/// coordinates (the shift and the scramble move no mass), wherever the pixel.
#[test]
fn interleaved_branches_are_uniform_on_average() {
    let mut sum = [0.0f64; 4];
    let count = 16_384;
    for p in 0..count {
        let xy = [(p * 7) % 61, (p * 13) % 59];
        let s = SobolStream::interleaved(p as u64, Stream::Camera, 5, xy, (p % 5) as u64);
        let mut b = s.branch(Branch::Gather, p % 3, 3);
        for d in sum.iter_mut() {
            *d += b.next_f32() as f64;
        }
    }
    for (d, v) in sum.iter().enumerate() {
        let mean = v / count as f64;
        assert!((mean - 0.5).abs() < 0.01, "dimension {d}: mean {mean}");
    }
}
