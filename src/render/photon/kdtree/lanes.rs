//! The leaf scan's arithmetic: four squared distances at once, in glam's 4-lane vectors
//! (SSE2 on x86-64, as `geometry/flat.rs` tests four primitives at once).

use glam::{Vec3A, Vec4};

use super::KdItem;

/// Squared distances from `q` to four items' positions, each bit for bit what
/// `(position - q).length_squared()` gives: glam sums (x^2 + y^2) + z^2, and so does this,
/// lane by lane (a unit test checks).
#[inline]
pub(in crate::render::photon) fn distances4<T: KdItem>(q: Vec3A, four: &[T; 4]) -> Vec4 {
    let [a, b, c, d] = four.each_ref().map(|it| it.position() - q);
    let x = Vec4::new(a.x, b.x, c.x, d.x);
    let y = Vec4::new(a.y, b.y, c.y, d.y);
    let z = Vec4::new(a.z, b.z, c.z, d.z);
    x * x + y * y + z * z
}

/// Bit j set where lane j of `d2` is at most `bound` (clear for NaN).
#[inline]
pub(in crate::render::photon) fn within4(d2: Vec4, bound: f32) -> u32 {
    d2.cmple(Vec4::splat(bound)).bitmask()
}
