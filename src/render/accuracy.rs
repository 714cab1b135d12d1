//! Error of an image against a reference: the metrics of `../shared/refcheck/compare.py`,
//! computed the same way so that numbers printed by `photonbox` and by refcheck agree
//! (docs/accuracy.md defines them).

use serde::{Deserialize, Serialize};

use crate::render::film::Image;

/// Rec. 709 luminance weights.
const LUM: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Block side of `block_err`, in pixels.
pub const BLOCK: u32 = 8;

/// The error of a test image A against a reference B.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageError {
    /// mean((a - b)^2 / (b^2 + 0.01)) over pixels and channels: noise and bias together.
    pub relmse: f64,
    /// Mean over 8x8-pixel blocks of |A_k - B_k| / max(B_k, 0.01 mean(B)), on luminance
    /// block means: bias, which noise averaging hides from `relmse`.
    pub block_err: f64,
    /// mean(A) / mean(B) of luminance: energy (normalisation) errors.
    pub mean_ratio: f64,
    /// sqrt(mean((a - b)^2)) over pixels and channels.
    pub rmse: f64,
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the reference is {ref_w}x{ref_h}, the image {w}x{h}: render at the reference's size")]
pub struct SizeMismatch {
    pub w: u32,
    pub h: u32,
    pub ref_w: u32,
    pub ref_h: u32,
}

/// Compare `a` against the reference `b` (non-finite values count as 0, as in compare.py).
pub fn compare(a: &Image, b: &Image) -> Result<ImageError, SizeMismatch> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(SizeMismatch {
            w: a.width,
            h: a.height,
            ref_w: b.width,
            ref_h: b.height,
        });
    }
    let fin = |v: f32| if v.is_finite() { v as f64 } else { 0.0 };
    let lum = |p: &[f32; 3]| (0..3).map(|c| fin(p[c]) * LUM[c]).sum::<f64>();
    let n = a.pixels.len().max(1) as f64;
    let (mut rel, mut sq, mut la_sum, mut lb_sum) = (0.0, 0.0, 0.0, 0.0);
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let (x, y) = (fin(pa[c]), fin(pb[c]));
            let d = x - y;
            rel += d * d / (y * y + 1e-2);
            sq += d * d;
        }
        la_sum += lum(pa);
        lb_sum += lum(pb);
    }
    let (la_mean, lb_mean) = (la_sum / n, lb_sum / n);

    // Block means of luminance over whole blocks (a partial edge block is left out).
    let (mut hb, mut wb, mut block) = (a.height / BLOCK, a.width / BLOCK, BLOCK);
    if hb == 0 || wb == 0 {
        (hb, wb, block) = (1, 1, a.width.min(a.height));
    }
    let floor = (0.01 * lb_mean).max(1e-12);
    let mut block_sum = 0.0;
    for by in 0..hb {
        for bx in 0..wb {
            let (mut sa, mut sb) = (0.0, 0.0);
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    sa += lum(&a.get(x, y));
                    sb += lum(&b.get(x, y));
                }
            }
            let area = (block * block) as f64;
            let (ma, mb) = (sa / area, sb / area);
            block_sum += (ma - mb).abs() / mb.max(floor);
        }
    }
    Ok(ImageError {
        relmse: rel / (3.0 * n),
        block_err: block_sum / (hb * wb) as f64,
        mean_ratio: la_mean / lb_mean.max(1e-30),
        rmse: (sq / (3.0 * n)).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: u32, h: u32, v: f32) -> Image {
        Image {
            width: w,
            height: h,
            pixels: vec![[v; 3]; (w * h) as usize],
        }
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = flat(16, 16, 0.5);
        let e = compare(&a, &a).unwrap();
        assert_eq!((e.relmse, e.block_err, e.rmse), (0.0, 0.0, 0.0));
        assert_eq!(e.mean_ratio, 1.0);
    }

    #[test]
    fn a_uniform_bias_shows_in_every_metric() {
        let (a, b) = (flat(16, 16, 1.1), flat(16, 16, 1.0));
        let e = compare(&a, &b).unwrap();
        assert!((e.mean_ratio - 1.1).abs() < 1e-6);
        assert!((e.block_err - 0.1).abs() < 1e-6);
        assert!((e.relmse - 0.01 / 1.01).abs() < 1e-6);
        assert!((e.rmse - 0.1).abs() < 1e-6);
    }

    #[test]
    fn sizes_must_match() {
        assert!(compare(&flat(8, 8, 1.0), &flat(8, 16, 1.0)).is_err());
    }
}
