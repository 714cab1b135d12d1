//! Quasi-random streams for the progressive path integrators (pt, lt, bdpt, vcm) and the
//! camera passes of raytrace, photon and ppm: iteration n of a pixel (or of a light-path
//! slot) draws the n-th point of an Owen-scrambled Sobol
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
//! iteration, dimension), and for a final gather's interleaved rays of the pixel's column
//! and row too ([`SobolStream::interleaved`]): the bytes do not depend on the thread count,
//! and a resumed render continues the same sequences.

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

/// What a stream's branches are for: each kind is a sequence of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branch {
    /// A final gather's rays (interleaved in an interleaved stream).
    Gather,
    /// The shadow rays to an area light beyond a sample's first (the pixel's own).
    Shadow,
    /// The rays over a pixel that read the light surfaces seen first (`integrator/seen.rs`;
    /// the pixel's own).
    SeenLight,
}

impl Branch {
    /// Mixed into the stream's seed.
    fn tag(self) -> u64 {
        match self {
            Branch::Gather => BRANCH,
            Branch::Shadow => BRANCH ^ 0x0000_0000_0000_5348,
            Branch::SeenLight => BRANCH ^ 0x0000_0000_0053_4c00,
        }
    }
}

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
    /// What the pixel's tile shares with this stream, if it is interleaved.
    tile: Tile,
}

/// A stream's part in the interleaving of a tile's final gathers
/// ([`SobolStream::interleaved`]).
#[derive(Clone, Copy)]
enum Tile {
    /// Not interleaved.
    Own,
    /// A camera sample's stream: its branches are interleaved, from the tile's sequence
    /// of branches under `seed`.
    Branches(Slot),
    /// A branch: its first 4D set is the point of the tile's sequence under `seed`,
    /// shifted by the slot's.
    FirstSet(Slot),
}

/// A sequence the pixels of a tile share, and the pixel's place among them.
#[derive(Clone, Copy)]
struct Slot {
    seed: u64,
    /// The pixel's position along the tile's Z-order curve.
    slot: u32,
}

/// The seed of a sequence of `stream` (its kind mixed in as `tag`) for `index` at
/// iteration `n`: each block of [`BLOCK`] iterations a fresh one.
fn sequence_seed(seed: u64, tag: u64, index: u64, n: u64) -> u64 {
    let a = splitmix64(seed ^ splitmix64(tag));
    splitmix64(a ^ splitmix64(index) ^ splitmix64(n / BLOCK).rotate_left(17))
}

/// Pixels a side of a tile whose final gathers are interleaved: 16 x 16 lowered the
/// block error of a room's first passes more than 8 x 8, and 32 x 32 no further
/// (docs/performance-history.md, "interleaved final gathers").
const TILE_SIDE: u32 = 16;

/// The bits of each coordinate that a pixel's shift sets: the Sobol sequence's first
/// `TILE_SIDE^2` points are multiples of 2^-SLOT_BITS.
const SLOT_BITS: u32 = 2 * TILE_SIDE.ilog2();
const _: () = assert!(TILE_SIDE.is_power_of_two() && SLOT_BITS <= 8);

/// Mixed into a tile's seed.
const TILE: u64 = 0x7469_6c65_0000_0000;

impl SobolStream {
    /// The stream of path `index` of `stream` at iteration `n` (0-based).
    pub fn new(seed: u64, stream: Stream, index: u64, n: u64) -> SobolStream {
        SobolStream {
            index: (n % BLOCK) as u32,
            seed: sequence_seed(seed, stream as u64 | 0x716d_6300_0000_0000, index, n),
            dim: 0,
            set: [0.0; 4],
            tile: Tile::Own,
        }
    }

    /// The stream of the pixel at `[x, y]` (its index `pixel`) at iteration `n` (0-based)
    /// of `stream`, its branches interleaved between the pixels of its tile (Keller and
    /// Heidrich, "Interleaved Sampling", 2001): the first 4D set of every branch comes from
    /// a sequence the tile's pixels share, XORed with the pixel's own point of the Sobol
    /// sequence's first `TILE_SIDE^2` (a net, placed along the Z-order curve so that every
    /// aligned square of pixels holds a net of its own), its bits below those
    /// Owen-scrambled for the pixel alone ([`scramble_within_slot`]). An XOR and a nested
    /// scramble keep a net a net and each point uniform, so a pixel's gather directions
    /// over its samples are as stratified as before and its expectation the same; one
    /// iteration's directions over a tile are now stratified together too, where they were
    /// independent from pixel to pixel: lower variance in any mean over neighbours (the
    /// error measured in blocks, and what smoothed gathers share). The sample's own draws
    /// and the branches' later sets stay the pixel's own: interleaving the camera sample's
    /// first set too (its jitter and light sample) raised cornell's block error after a
    /// few passes.
    pub fn interleaved(seed: u64, stream: Stream, pixel: u64, [x, y]: [u32; 2], n: u64) -> Self {
        let tile = (x / TILE_SIDE) as u64 | ((y / TILE_SIDE) as u64) << 32;
        let shared = sequence_seed(seed, stream as u64 | TILE, tile, n);
        SobolStream {
            tile: Tile::Branches(Slot {
                seed: splitmix64(shared ^ BRANCH),
                slot: morton(x % TILE_SIDE, y % TILE_SIDE),
            }),
            ..SobolStream::new(seed, stream, pixel, n)
        }
    }

    /// Branch `k` of `count` of `kind` leaving this point (a final gather's rays, a
    /// sample's shadow rays): point `index * count + k` of a sequence of its own, so that
    /// the branches of the first n points of this sequence are the first n * count points
    /// of theirs, stratified together (a pixel's gather rays over all of its samples). In
    /// an interleaved stream a gather's branches' first sets are interleaved too, from the
    /// tile's sequence of branches.
    pub fn branch(&self, kind: Branch, k: u32, count: u32) -> SobolStream {
        let wide = self.index as u64 * count as u64 + k as u64;
        let block = splitmix64(wide / BLOCK);
        SobolStream {
            index: (wide % BLOCK) as u32,
            seed: splitmix64(self.seed ^ kind.tag() ^ block),
            dim: 0,
            set: [0.0; 4],
            tile: match self.tile {
                Tile::Branches(t) if kind == Branch::Gather => Tile::FirstSet(Slot {
                    seed: splitmix64(t.seed ^ block),
                    ..t
                }),
                _ => Tile::Own,
            },
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
        self.set = match self.tile {
            Tile::FirstSet(Slot { seed, slot }) if set == 0 => {
                // The slot's point of the Sobol sequence, its bits reversed: the table
                // of indices whose set bits are in the top byte.
                let shift = tables().high[(slot.reverse_bits() >> 24) as usize];
                let shifted = first_four_rev(self.index, seed as u32) ^ shift;
                scramble_within_slot(shifted, self.seed)
                    .reverse_bits()
                    .to_f32_norm()
            }
            _ => {
                let seed = splitmix64(self.seed ^ set.wrapping_mul(0x9e37_79b9_7f4a_7c15));
                first_four(self.index, seed as u32)
            }
        };
    }
}

/// `sobol_burley::sample_4d(index, 0, seed)`, the same bits, with the Sobol part read from
/// two tables of 256 entries instead of one XOR per set bit of the shuffled index (the
/// points are linear in the index's bits over GF(2)): the sampler was a quarter of a `pt`
/// pass with the crate's loop (benches/qmc.rs compares the two).
#[inline]
pub fn first_four(index: u32, seed: u32) -> [f32; 4] {
    first_four_rev(index, seed).reverse_bits().to_f32_norm()
}

/// [`first_four`] as 32-bit fixed-point fractions, their bits reversed (as the crate's
/// scrambles take them).
#[inline]
fn first_four_rev(index: u32, seed: u32) -> Int4 {
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
}

/// `x_rev` (fractions with their bits reversed) with every bit finer than the top
/// [`SLOT_BITS`] of the fraction (bit `SLOT_BITS` and up of `x_rev`) Owen-scrambled under
/// `seed` (each flip a hash of the coarser bits: a nested scramble, Owen 1995), the bits
/// a shift sets kept. Without it a tile's pixels, once their own points fill the shifts'
/// grid, would hold the same offsets within its cells, only in other cells (an XOR shift
/// swaps whole cells), and their errors would go together.
#[inline]
fn scramble_within_slot(x_rev: Int4, seed: u64) -> Int4 {
    let (a, b) = (seed as u32, (seed >> 32) as u32);
    let scramble = hash_int4([a, a ^ 0x5bd1_e995, b, b ^ 0x68e3_1da4].into());
    let fine = owen_scramble_int4_rev(x_rev, scramble);
    let slot: Int4 = [!(!0u32 << SLOT_BITS); 4].into();
    let below: Int4 = [!0u32 << SLOT_BITS; 4].into();
    (x_rev & slot) | (fine & below)
}

/// The position of `[x, y]` (each below [`TILE_SIDE`]) along the Z-order curve: the pixels
/// of every aligned square of 2^k a side hold 4^k consecutive positions.
fn morton(x: u32, y: u32) -> u32 {
    (0..TILE_SIDE.ilog2()).fold(0, |m, b| {
        m | ((x >> b) & 1) << (2 * b) | ((y >> b) & 1) << (2 * b + 1)
    })
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
mod tests;
