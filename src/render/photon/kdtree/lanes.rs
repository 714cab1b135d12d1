//! The leaf scan's arithmetic: four squared distances at once (SSE2 on x86-64).

use glam::Vec3A;

use super::KdItem;

/// Squared distances from `q` to four items' positions, each bit for bit what
/// `(position - q).length_squared()` gives ((x^2 + y^2) + z^2, as glam sums it).
#[inline]
pub(super) fn distances4<T: KdItem>(q: Vec3A, four: &[T]) -> [f32; 4] {
    let p = [
        four[0].position() - q,
        four[1].position() - q,
        four[2].position() - q,
        four[3].position() - q,
    ];
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of the x86_64 baseline.
        unsafe {
            let [a, b, c, d]: [__m128; 4] = p.map(Into::into);
            let ab_lo = _mm_unpacklo_ps(a, b);
            let cd_lo = _mm_unpacklo_ps(c, d);
            let ab_hi = _mm_unpackhi_ps(a, b);
            let cd_hi = _mm_unpackhi_ps(c, d);
            let x = _mm_movelh_ps(ab_lo, cd_lo);
            let y = _mm_movehl_ps(cd_lo, ab_lo);
            let z = _mm_movelh_ps(ab_hi, cd_hi);
            let d2 = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(x, x), _mm_mul_ps(y, y)),
                _mm_mul_ps(z, z),
            );
            let mut out = [0.0f32; 4];
            _mm_storeu_ps(out.as_mut_ptr(), d2);
            out
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        p.map(|v| v.length_squared())
    }
}

/// Bit j set where `d2[j] <= bound`.
#[inline]
pub(super) fn within4(d2: [f32; 4], bound: f32) -> u32 {
    d2.iter()
        .enumerate()
        .fold(0, |m, (j, &d)| m | (((d <= bound) as u32) << j))
}
