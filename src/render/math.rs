//! Small numeric helpers shared by the whole engine: colours, floating-point error bounds,
//! orthonormal frames, a fast sin/cos.

use glam::Vec3A;

/// Linear RGB radiometric quantity (radiance, flux, reflectance). A plain alias: colours and
/// vectors share glam's SIMD type, and the names at each use say which one is meant.
pub type Rgb = Vec3A;

/// Rec. 709 luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// [`luminance`] of an f64 triple (sums of many values).
#[inline]
pub fn luminance_f64(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Largest component, used for Russian-roulette survival probabilities.
#[inline]
pub fn max_component(c: Rgb) -> f32 {
    c.x.max(c.y).max(c.z)
}

/// `gamma(n)` bounds the relative error of `n` chained floating-point operations
/// (Higham; pbrt-v4 section 6.8.1): |computed - exact| <= gamma(n) * |exact|.
#[inline]
pub const fn gamma(n: i32) -> f32 {
    let eps = f32::EPSILON * 0.5;
    (n as f32 * eps) / (1.0 - n as f32 * eps)
}

/// The next representable f32 above `v` (pbrt-v4 `NextFloatUp`).
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable f32 below `v` (pbrt-v4 `NextFloatDown`).
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// An orthonormal frame around a unit normal, to move directions between world space and
/// the local shading space where the normal is +z.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3A,
    pub t: Vec3A,
    pub n: Vec3A,
}

impl Frame {
    /// Branchless basis from a unit vector: Duff et al. 2017, "Building an Orthonormal Basis,
    /// Revisited" (JCGT 6(1)); continuous everywhere but at one point, and exact to rounding.
    #[inline]
    pub fn from_normal(n: Vec3A) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3A::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    #[inline]
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// sin and cos of 2 pi `u` for `u` in [0, 1] (an angle in turns, as sampling draws it), to
/// about 3e-7. The angle is folded onto [-pi/2, pi/2] by its symmetries alone (a subtraction
/// and an absolute value, no quadrant index), and Taylor polynomials cover that interval
/// (their first omitted terms are below 6e-8 there). Sampling calls this once or twice per
/// bounce: libm's `sincosf` showed up in photon tracing's profile, and the quadrant-reducing
/// version this replaced spent a float-to-int conversion and a four-way jump on every call.
/// The polynomials are evaluated in Estrin's scheme (powers y, y^2, y^4 of psi^2), a shorter
/// dependency chain than Horner's (measured: docs/performance-history.md, "sine and cosine
/// in turns").
#[inline]
pub fn sin_cos_turns(u: f32) -> (f32, f32) {
    use std::f32::consts::TAU;
    // 2 pi u = 2 pi x + pi; |2 pi x| = psi + pi/2 with psi in [-pi/2, pi/2].
    let x = u - 0.5;
    let psi = (x.abs() - 0.25) * TAU;
    let y = psi * psi;
    let y2 = y * y;
    let y4 = y2 * y2;
    let sin_psi = psi
        * ((1.0 - y * (1.0 / 6.0))
            + y2 * (1.0 / 120.0 - y * (1.0 / 5040.0))
            + y4 * (1.0 / 362_880.0 - y * (1.0 / 39_916_800.0)));
    let cos_psi = (1.0 - y * 0.5)
        + y2 * (1.0 / 24.0 - y * (1.0 / 720.0))
        + y4 * ((1.0 / 40320.0 - y * (1.0 / 3_628_800.0)) + y2 * (1.0 / 479_001_600.0));
    // sin(2 pi u) = -sin(2 pi x) = -sign(x) cos(psi); cos(2 pi u) = -cos(2 pi |x|) = sin(psi).
    (cos_psi.copysign(-x), sin_psi)
}

/// Round half away from zero by truncation (no libm call on baseline x86-64).
#[inline]
pub fn round_to_i32(x: f32) -> i32 {
    (x + 0.5f32.copysign(x)) as i32
}

/// Mirror reflection of `wo` about the unit normal `n` (both pointing away from the surface).
#[inline]
pub fn reflect(wo: Vec3A, n: Vec3A) -> Vec3A {
    2.0 * wo.dot(n) * n - wo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal_for_many_normals() {
        for i in 0..1000 {
            let a = i as f32 * 0.731;
            let b = i as f32 * 0.377;
            let n = Vec3A::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos()).normalize();
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!(
                f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5
            );
            let v = Vec3A::new(0.3, -0.5, 0.81);
            let w = f.to_world(v);
            let back = Vec3A::new(w.dot(f.s), w.dot(f.t), w.dot(f.n));
            assert!((back - v).length() < 1e-5);
        }
    }

    #[test]
    fn sin_cos_in_turns_is_accurate_over_the_turn() {
        for i in 0..=100_000 {
            let u = i as f32 / 100_000.0;
            let (s, c) = sin_cos_turns(u);
            let phi = std::f64::consts::TAU * u as f64;
            let (es, ec) = phi.sin_cos();
            assert!(
                (s as f64 - es).abs() < 5e-7 && (c as f64 - ec).abs() < 5e-7,
                "u = {u}: ({s}, {c}) against ({es}, {ec})"
            );
        }
    }

    #[test]
    fn next_float_moves_one_ulp() {
        assert!(next_float_up(1.0) > 1.0 && next_float_down(1.0) < 1.0);
        assert!(next_float_up(-0.0) > 0.0 && next_float_down(0.0) < 0.0);
        assert_eq!(next_float_up(1.0) - 1.0, f32::EPSILON);
    }
}

/// Neumaier's compensated summation (an improved Kahan sum) in f64, per channel: the
/// total of 1e8 photon powers comes out exact to the last bits of f64, where an f32 sum
/// would stall once the total dwarfs each term (tests/stability_transport.rs).
#[derive(Clone, Copy, Debug, Default)]
pub struct CompensatedSum {
    sum: [f64; 3],
    compensation: [f64; 3],
}

impl CompensatedSum {
    #[inline]
    pub fn add(&mut self, v: Rgb) {
        for (i, x) in v.to_array().into_iter().enumerate() {
            let (s, x) = (self.sum[i], x as f64);
            let t = s + x;
            self.compensation[i] += if s.abs() >= x.abs() {
                (s - t) + x
            } else {
                (x - t) + s
            };
            self.sum[i] = t;
        }
    }

    pub fn total(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.sum[i] + self.compensation[i])
    }
}
