//! The watertight ray-triangle test for `Shape::Triangle`: the shear into ray space, edge
//! functions by a compensated difference of products, and pbrt-v4's conservative bound on
//! t. Apart from `shapes.rs` because it is an algorithm of its own, longer than the sphere
//! and quad tests together; `triangle_f64.rs` redoes it in f64 when the bound cannot place
//! a hit in front of the origin.

use glam::Vec3A;

use super::Ray;
use super::shapes::ShapeHit;
use crate::render::math::gamma;

/// a*b - c*d as the f32 nearest the exact value, or next to it: both products are exact in
/// f64 (24-bit significands), and their difference rounds once there. At least as accurate
/// as Kahan's FMA-compensated form (pbrt-v4 B.2.9), which without a hardware FMA target
/// compiles to calls; see docs/performance-history.md.
#[inline]
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    (a as f64 * b as f64 - c as f64 * d as f64) as f32
}

#[inline]
fn permute(v: Vec3A, x: usize, y: usize, z: usize) -> Vec3A {
    Vec3A::new(v[x], v[y], v[z])
}

/// Watertight ray-triangle intersection (Woop, Benthin and Wald, "Watertight Ray/Triangle
/// Intersection", JCGT 2(1), 2013, as in pbrt-v4 6.5.3): no ray slips between two triangles
/// sharing an edge, so closed meshes never leak. The conservative test on t at the end
/// (pbrt-v4's deltaT) rejects hits not provably in front of the origin.
#[inline]
pub(super) fn intersect_triangle(p0: Vec3A, p1: Vec3A, p2: Vec3A, ray: &Ray) -> Option<ShapeHit> {
    let ad = ray.d.abs();
    let kz = if ad.x > ad.y {
        if ad.x > ad.z { 0 } else { 2 }
    } else if ad.y > ad.z {
        1
    } else {
        2
    };
    let kx = (kz + 1) % 3;
    let ky = (kx + 1) % 3;
    let d = permute(ray.d, kx, ky, kz);
    let mut a = permute(p0 - ray.o, kx, ky, kz);
    let mut b = permute(p1 - ray.o, kx, ky, kz);
    let mut c = permute(p2 - ray.o, kx, ky, kz);
    let sx = -d.x / d.z;
    let sy = -d.y / d.z;
    let sz = 1.0 / d.z;
    for p in [&mut a, &mut b, &mut c] {
        p.x += sx * p.z;
        p.y += sy * p.z;
    }
    // Edge functions, their signs exact (see difference_of_products).
    let e0 = difference_of_products(b.x, c.y, b.y, c.x);
    let e1 = difference_of_products(c.x, a.y, c.y, a.x);
    let e2 = difference_of_products(a.x, b.y, a.y, b.x);
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    a.z *= sz;
    b.z *= sz;
    c.z *= sz;
    let t_scaled = e0 * a.z + e1 * b.z + e2 * c.z;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < ray.t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > ray.t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // Conservative bound on the error of t (pbrt-v4, "Ensure that computed triangle t is
    // conservatively greater than zero").
    let max_zt = a.z.abs().max(b.z.abs()).max(c.z.abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = a.x.abs().max(b.x.abs()).max(c.x.abs());
    let max_yt = a.y.abs().max(b.y.abs()).max(c.y.abs());
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        // Not provably in front in f32; f64 can tell (see triangle_f64.rs). Rare: only
        // hits very near the origin relative to the triangle's size get here.
        return super::triangle_f64::intersect_triangle_f64(p0, p1, p2, ray);
    }
    Some(ShapeHit {
        t,
        uv: [e1 * inv_det, e2 * inv_det],
    })
}
