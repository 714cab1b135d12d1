//! Quasi-random streams for the progressive path integrators (pt, lt, bdpt, vcm): iteration n
//! of a pixel (or of a light-path slot) draws the n-th point of an Owen-scrambled Sobol
//! sequence of its own, so that across iterations the first 2D and 4D projections of every
//! path (the pixel position, the first bounce, the light sample) are stratified instead of
//! independent. Same expectation, lower variance: the error of a path tracer with an
//! independent sampler (Mitsuba's default) falls as n^-1/2, stratified smooth dimensions
//! faster (Owen 1997; Burley, "Practical Hash-based Owen Scrambling", JCGT 2020).
//!
//! The points come from `sobol_burley` (Burley's scrambling and index shuffling, Vegdahl's
//! hash). Dimensions are padded as Burley proposes: every four dimensions reuse the
//! sequence's first four under a new seed, so each 4D set is stratified within itself and
//! independent of the others. Each draw is a pure function of (seed, stream, index,
//! iteration, dimension): the bytes do not depend on the thread count, and a resumed render
//! continues the same sequences.

use std::sync::OnceLock;

use sobol_burley::parts::{
    Int4, hash, hash_int4, owen_scramble_int4_rev, owen_scramble_rev, sobol_int4_rev,
};

use crate::render::sampling::{Stream, splitmix64};

/// The longest sequence the crate stratifies; iteration n uses point n mod this of a
/// sequence seeded with n / this, so a longer render stays unbiased (each block of
/// iterations is a fresh scrambled sequence).
const BLOCK: u64 = 1 << 16;

/// Mixed into a stream's seed for the sequence of its branches.
const BRANCH: u64 = 0x6272_616e_6368_0000;

/// A stream of one path's quasi-random numbers: the `n`-th point of its own sequence, one
/// coordinate per draw.
pub struct SobolStream {
    /// The point's index within its block.
    index: u32,
    /// The sequence's seed: (seed, stream, index, block) hashed.
    seed: u64,
    /// The next dimension to draw.
    dim: u32,
    /// The current 4D set's coordinates.
    set: [f32; 4],
}

impl SobolStream {
    /// The stream of path `index` of `stream` at iteration `n` (0-based).
    pub fn new(seed: u64, stream: Stream, index: u64, n: u64) -> SobolStream {
        let a = splitmix64(seed ^ splitmix64(stream as u64 | 0x716d_6300_0000_0000));
        let b = splitmix64(a ^ splitmix64(index) ^ splitmix64(n / BLOCK).rotate_left(17));
        SobolStream {
            index: (n % BLOCK) as u32,
            seed: b,
            dim: 0,
            set: [0.0; 4],
        }
    }

    /// Branch `k` of `count` leaving this point (a final gather's rays): point
    /// `index * count + k` of a sequence of its own, so that the branches of the first n
    /// points of this sequence are the first n * count points of theirs, stratified
    /// together (a pixel's gather rays over all of its samples).
    pub fn branch(&self, k: u32, count: u32) -> SobolStream {
        let wide = self.index as u64 * count as u64 + k as u64;
        SobolStream {
            index: (wide % BLOCK) as u32,
            seed: splitmix64(self.seed ^ BRANCH ^ splitmix64(wide / BLOCK)),
            dim: 0,
            set: [0.0; 4],
        }
    }

    /// The next coordinate, in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        let k = (self.dim & 3) as usize;
        if k == 0 {
            self.refill();
        }
        self.dim += 1;
        self.set[k]
    }

    /// The next two coordinates, from one 4D set's first or last pair (both stratified in
    /// 2D), skipping a coordinate when a 1D draw left the set at an odd position.
    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        if self.dim & 1 == 1 {
            self.dim += 1;
        }
        let k = (self.dim & 3) as usize;
        if k == 0 {
            self.refill();
        }
        self.dim += 2;
        [self.set[k], self.set[k + 1]]
    }

    #[inline]
    fn refill(&mut self) {
        let set = (self.dim >> 2) as u64;
        let seed = splitmix64(self.seed ^ set.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        self.set = first_four(self.index, seed as u32);
    }
}

/// `sobol_burley::sample_4d(index, 0, seed)`, the same bits, with the Sobol part read from
/// two tables of 256 entries instead of one XOR per set bit of the shuffled index (the
/// points are linear in the index's bits over GF(2)): the sampler was a quarter of a `pt`
/// pass with the crate's loop (benches/qmc.rs compares the two).
#[inline]
pub fn first_four(index: u32, seed: u32) -> [f32; 4] {
    let t = tables();
    let shuffled = owen_scramble_rev(index.reverse_bits(), hash(seed ^ 0x79c6_8e4a));
    let sobol = t.high[(shuffled >> 24) as usize] ^ t.low[((shuffled >> 16) & 0xff) as usize];
    let scramble: Int4 = {
        let s = seed.wrapping_mul(0x9c8f_2d3b);
        [
            s ^ 0x912f_69ba,
            s ^ 0x174f_18ab,
            s ^ 0x691e_72ca,
            s ^ 0xb40c_c1b8,
        ]
        .into()
    };
    owen_scramble_int4_rev(sobol, hash_int4(scramble))
        .reverse_bits()
        .to_f32_norm()
}

/// The first four Sobol dimensions (bit-reversed) of the reversed indices whose only set
/// bits are in the top byte (`high`) or the next (`low`).
struct Tables {
    high: [Int4; 256],
    low: [Int4; 256],
}

fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| Tables {
        high: std::array::from_fn(|b| sobol_int4_rev((b as u32) << 24, 0)),
        low: std::array::from_fn(|b| sobol_int4_rev((b as u32) << 16, 0)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first 2^k points of a pixel's 2D projection fall one per cell of a 2^k grid of
    /// equal strips (a (0,2)-sequence after scrambling): the property the integrators rely
    /// on, and independent samples lack.
    #[test]
    fn each_pair_is_stratified_across_iterations() {
        for pair in 0..6 {
            let n = 256;
            let mut rows = vec![0u32; n];
            let mut cols = vec![0u32; n];
            for i in 0..n as u64 {
                let mut s = SobolStream::new(5, Stream::Camera, 77, i);
                for _ in 0..pair {
                    s.next_2d();
                }
                let [x, y] = s.next_2d();
                cols[(x * n as f32) as usize] += 1;
                rows[(y * n as f32) as usize] += 1;
            }
            assert!(
                cols.iter().all(|&c| c == 1),
                "pair {pair}: x not stratified"
            );
            assert!(
                rows.iter().all(|&c| c == 1),
                "pair {pair}: y not stratified"
            );
        }
    }

    /// The branches of a sequence's first points are one stratified set: 4 points with 8
    /// branches each give 32 first pairs, one in each of 32 equal strips in x and in y
    /// (a pixel's gather directions over its samples).
    #[test]
    fn branches_of_a_sequence_s_points_are_stratified_together() {
        let (points, branches) = (4u64, 8u32);
        let n = points as usize * branches as usize;
        let (mut cols, mut rows) = (vec![0u32; n], vec![0u32; n]);
        for j in 0..points {
            let mut s = SobolStream::new(5, Stream::Camera, 77, j);
            s.next_2d(); // the sample's own draws do not move its branches
            for k in 0..branches {
                let [x, y] = s.branch(k, branches).next_2d();
                cols[(x * n as f32) as usize] += 1;
                rows[(y * n as f32) as usize] += 1;
            }
        }
        assert!(cols.iter().all(|&c| c == 1), "x not stratified: {cols:?}");
        assert!(rows.iter().all(|&c| c == 1), "y not stratified: {rows:?}");
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
}
