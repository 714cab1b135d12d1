//! The sum of a progressive render's pass images, exact: each pass's value is rounded once to
//! a fixed-point integer (2^-60 units, i128), and integers add exactly, so the sum does not
//! depend on the order or grouping of its terms. That is what lets passes be rendered in
//! pieces (on several machines, in any order) and merged into the very bytes of one
//! uninterrupted run: a float sum would round differently for each grouping.
//!
//! Range and precision: values are clamped to +-2^40 (about 1.1e12, far above any radiance a
//! physical scene gives; non-finite samples never reach a pass image), so a term is at most
//! 2^100 units and i128 holds the sum of 2^26 passes of them, 67 times the most a render
//! may run (`spec::MAX_ITERATIONS`). The unit, 2^-60 (about 8.7e-19), is
//! below an f32's spacing for any value above 1e-12, so a pass's value is kept as the f32
//! the pass made.

use crate::render::film::Image;

/// Fractional bits of the fixed-point unit.
const FRACTION_BITS: i32 = 60;
/// Largest magnitude a pass value is taken at.
const LIMIT: f32 = (1u64 << 40) as f32;

/// Bytes of one pixel's sum as stored (three little-endian i128).
pub const PIXEL_BYTES: usize = 48;

/// A pass value in fixed point, rounded half away from zero (NaN, which a pass image never
/// holds, as 0). Worked out from the f32's bits, its mantissa shifted by its exponent: the
/// float-to-i128 conversion the compiler emits is a library call, about 3 times slower
/// (benches/pass_sum.rs; figures in docs/performance-history.md).
fn fixed(v: f32) -> i128 {
    let v = if v.is_nan() {
        0.0
    } else {
        v.clamp(-LIMIT, LIMIT)
    };
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32;
    let fraction = (bits & 0x7f_ffff) as i128;
    // v = mantissa * 2^power.
    let (mantissa, power) = match exponent {
        0 => (fraction, -149),
        _ => (fraction | 0x80_0000, exponent - 150),
    };
    let shift = power + FRACTION_BITS;
    let magnitude = if shift >= 0 {
        mantissa << shift
    } else if shift > -25 {
        (mantissa + (1 << (-shift - 1))) >> -shift
    } else {
        0
    };
    if bits >> 31 == 1 {
        -magnitude
    } else {
        magnitude
    }
}

/// An i128 as f64, from its magnitude's two halves (the library's conversion is a slow
/// call); within an ulp of the correctly rounded value, and the same bits on every run.
fn to_f64(x: i128) -> f64 {
    let m = x.unsigned_abs();
    let f = (m >> 64) as u64 as f64 * 2f64.powi(64) + m as u64 as f64;
    if x < 0 { -f } else { f }
}

/// The exact sum of some passes' images.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PassSum {
    pub width: u32,
    pub height: u32,
    pixels: Vec<[i128; 3]>,
}

impl PassSum {
    pub fn new(width: u32, height: u32) -> PassSum {
        PassSum {
            width,
            height,
            pixels: vec![[0; 3]; width as usize * height as usize],
        }
    }

    /// Add one pass's image (of this size).
    pub fn add_image(&mut self, pass: &Image) {
        for (s, p) in self.pixels.iter_mut().zip(&pass.pixels) {
            for c in 0..3 {
                s[c] += fixed(p[c]);
            }
        }
    }

    /// Add another sum of the same size: the result is the same bits whatever the order.
    pub fn merge(&mut self, other: &PassSum) {
        for (s, o) in self.pixels.iter_mut().zip(&other.pixels) {
            for c in 0..3 {
                s[c] += o[c];
            }
        }
    }

    /// The mean image over `passes` passes.
    pub fn mean(&self, passes: u32) -> Image {
        let scale = 2f64.powi(-FRACTION_BITS) / passes.max(1) as f64;
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .pixels
                .iter()
                .map(|p| p.map(|c| (to_f64(c) * scale) as f32))
                .collect(),
        }
    }

    /// The sum as little-endian i128 RGB triples, row-major.
    pub fn write_to(&self, buf: &mut Vec<u8>) {
        buf.reserve(self.pixels.len() * PIXEL_BYTES);
        for p in &self.pixels {
            for c in p {
                buf.extend_from_slice(&c.to_le_bytes());
            }
        }
    }

    /// The sum packed (a farm task's result): per value, the number of trailing zero bits
    /// of its zigzag form (one byte; 128 for zero), then the rest in LEB128. A pass value
    /// keeps only an f32's 24 significant bits in 2^-60 units, so the sum of a few passes
    /// packs to about a third of [`PassSum::write_to`]'s 48 bytes a pixel.
    pub fn write_packed(&self, buf: &mut Vec<u8>) {
        for &c in self.pixels.iter().flatten() {
            let z = ((c << 1) ^ (c >> 127)) as u128;
            if z == 0 {
                buf.push(128);
                continue;
            }
            let zeros = z.trailing_zeros();
            buf.push(zeros as u8);
            let mut rest = z >> zeros;
            while rest >= 0x80 {
                buf.push((rest as u8 & 0x7f) | 0x80);
                rest >>= 7;
            }
            buf.push(rest as u8);
        }
    }

    /// The sum [`PassSum::write_packed`] wrote, if `bytes` is exactly a width x height one.
    pub fn read_packed(width: u32, height: u32, bytes: &[u8]) -> Option<PassSum> {
        let n = (width as usize).checked_mul(height as usize)?;
        let mut at = 0;
        let mut value = || -> Option<i128> {
            let zeros = *bytes.get(at)? as u32;
            at += 1;
            if zeros == 128 {
                return Some(0);
            }
            let mut rest = 0u128;
            for shift in (0..128).step_by(7) {
                let b = *bytes.get(at)?;
                at += 1;
                let bits = (b & 0x7f) as u128;
                if (bits << shift) >> shift != bits {
                    return None;
                }
                rest |= bits << shift;
                if b & 0x80 == 0 {
                    if zeros > 127 || rest.leading_zeros() < zeros {
                        return None;
                    }
                    let z = rest << zeros;
                    return Some(((z >> 1) as i128) ^ -((z & 1) as i128));
                }
            }
            None
        };
        let mut pixels = Vec::with_capacity(n.min(bytes.len() / 3));
        for _ in 0..n {
            pixels.push([value()?, value()?, value()?]);
        }
        (at == bytes.len()).then_some(PassSum {
            width,
            height,
            pixels,
        })
    }

    /// The sum [`PassSum::write_to`] wrote, if `bytes` is exactly a width x height one.
    pub fn read_from(width: u32, height: u32, bytes: &[u8]) -> Option<PassSum> {
        let n = (width as usize).checked_mul(height as usize)?;
        if bytes.len() != n.checked_mul(PIXEL_BYTES)? {
            return None;
        }
        let pixels = bytes
            .chunks_exact(PIXEL_BYTES)
            .map(|px| {
                let c = |i: usize| i128::from_le_bytes(px[16 * i..16 * i + 16].try_into().unwrap());
                [c(0), c(1), c(2)]
            })
            .collect();
        Some(PassSum {
            width,
            height,
            pixels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Images with the dynamic range of real passes: dark pixels, bright ones, fireflies.
    fn passes(n: usize) -> Vec<Image> {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        (0..n)
            .map(|_| Image {
                width: 4,
                height: 2,
                pixels: (0..8)
                    .map(|_| [(); 3].map(|_| 10f32.powf(rng.random_range(-9.0..7.0))))
                    .collect(),
            })
            .collect()
    }

    #[test]
    fn any_split_of_the_passes_merges_to_the_same_bits() {
        let images = passes(50);
        let mut whole = PassSum::new(4, 2);
        images.iter().for_each(|p| whole.add_image(p));
        for split in [1, 7, 13, 25] {
            // Pieces summed on their own, merged last piece first.
            let mut pieces: Vec<PassSum> = images
                .chunks(split)
                .map(|c| {
                    let mut s = PassSum::new(4, 2);
                    c.iter().for_each(|p| s.add_image(p));
                    s
                })
                .collect();
            pieces.reverse();
            let mut merged = PassSum::new(4, 2);
            pieces.iter().for_each(|p| merged.merge(p));
            assert_eq!(merged, whole, "split into pieces of {split}");
        }
        // A float sum would not have been the same bits (what this type is for).
        let f64_sum = |order: &mut dyn Iterator<Item = &Image>| {
            let mut s = [0f64; 24];
            for p in order {
                for (i, v) in p.pixels.iter().flatten().enumerate() {
                    s[i] += *v as f64;
                }
            }
            s
        };
        assert_ne!(
            f64_sum(&mut images.iter()),
            f64_sum(&mut images.iter().rev())
        );
    }

    #[test]
    fn the_mean_keeps_each_pass_value() {
        let images = passes(3);
        let mut s = PassSum::new(4, 2);
        s.add_image(&images[0]);
        // One pass: its own f32 values back (every value here is above 1e-9).
        assert_eq!(s.mean(1).pixels, images[0].pixels);
        s.add_image(&images[1]);
        s.add_image(&images[2]);
        for (i, px) in s.mean(3).pixels.iter().enumerate() {
            for c in 0..3 {
                let exact = images.iter().map(|p| p.pixels[i][c] as f64).sum::<f64>() / 3.0;
                assert!(((px[c] as f64) - exact).abs() <= exact * 1e-7, "{px:?}");
            }
        }
    }

    #[test]
    fn a_sum_round_trips_through_its_bytes() {
        let mut s = PassSum::new(4, 2);
        passes(4).iter().for_each(|p| s.add_image(p));
        let mut buf = Vec::new();
        s.write_to(&mut buf);
        assert_eq!(buf.len(), 8 * PIXEL_BYTES);
        assert_eq!(PassSum::read_from(4, 2, &buf), Some(s));
        assert_eq!(PassSum::read_from(4, 2, &buf[1..]), None);
        assert_eq!(PassSum::read_from(8, 2, &buf), None);
    }

    /// Packed, a sum comes back bit for bit, extremes and negatives included, in about a
    /// third of the bytes; a short, long or overflowing input is refused.
    #[test]
    fn a_sum_round_trips_packed_in_fewer_bytes() {
        let mut s = PassSum::new(4, 2);
        passes(3).iter().for_each(|p| s.add_image(p));
        s.pixels[0] = [0, -1, i128::MAX];
        s.pixels[1] = [i128::MIN, -(3 << 70), 1];
        let mut packed = Vec::new();
        s.write_packed(&mut packed);
        assert_eq!(PassSum::read_packed(4, 2, &packed), Some(s.clone()));
        let mut plain = PassSum::new(4, 2);
        passes(3).iter().for_each(|p| plain.add_image(p));
        let mut small = Vec::new();
        plain.write_packed(&mut small);
        assert!(
            small.len() * 3 < 8 * PIXEL_BYTES * 2,
            "{} bytes",
            small.len()
        );
        assert_eq!(
            PassSum::read_packed(4, 2, &packed[..packed.len() - 1]),
            None
        );
        assert_eq!(
            PassSum::read_packed(4, 2, &[packed.as_slice(), &[128]].concat()),
            None
        );
        assert_eq!(PassSum::read_packed(1, 1, &[0, 0xff, 0xff, 0xff]), None);
        let too_wide = [&[100u8][..], &[0xff; 18], &[0x7f], &[128, 128]].concat();
        assert_eq!(PassSum::read_packed(1, 1, &too_wide), None);
    }

    #[test]
    fn fixed_point_from_the_bits_is_the_rounded_product() {
        let reference = |v: f32| ((v as f64) * 2f64.powi(FRACTION_BITS)).round() as i128;
        let mut x = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = f32::from_bits(x as u32);
            if v.is_finite() && v.abs() <= LIMIT {
                assert_eq!(fixed(v), reference(v), "{v:e}");
            }
        }
        // Half-way cases round away from zero; subnormals and tiny values to 0.
        for v in [
            2f32.powi(-61),
            -2f32.powi(-61),
            3.0 * 2f32.powi(-62),
            1e-30,
            f32::MIN_POSITIVE / 4.0,
        ] {
            assert_eq!(fixed(v), reference(v), "{v:e}");
        }
        for x in [0i128, 1, -1, 1 << 70, -(1 << 70) + 12345, (1 << 100) + 1] {
            assert!(
                (to_f64(x) - x as f64).abs() <= (x as f64).abs() * f64::EPSILON,
                "{x}"
            );
        }
    }

    #[test]
    fn out_of_range_values_are_clamped_not_wrapped() {
        let mut s = PassSum::new(1, 1);
        let huge = Image {
            width: 1,
            height: 1,
            pixels: vec![[f32::MAX, -f32::MAX, f32::NAN]],
        };
        for _ in 0..1000 {
            s.add_image(&huge);
        }
        let m = s.mean(1000).pixels[0];
        assert_eq!(m, [LIMIT, -LIMIT, 0.0]);
    }
}
