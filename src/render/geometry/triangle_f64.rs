//! The watertight triangle test again in f64, for the hits the f32 test cannot prove to lie
//! in front of the ray's origin.
//!
//! pbrt-v4's bound on the error of t grows with the triangle's size measured from the ray's
//! origin (section 6.8.4). A ray leaving a surface a few thousandths of a unit from a huge
//! triangle (a face 2000 units wide, reached after a reflection near its edge) has a real
//! hit inside that bound, and the f32 test rejects it: the ray passes through the face and
//! light leaks (tests/stability_transport.rs, Snell's window). In f64 the same bound is
//! 2^29 times smaller, so such a hit is proven in front and kept; a ray that truly starts
//! on the triangle still gets t at or below the (f64) bound and no hit.

use glam::{DVec3, Vec3A};

use super::Ray;
use super::shapes::ShapeHit;

fn gamma64(n: i32) -> f64 {
    let eps = f64::EPSILON * 0.5;
    n as f64 * eps / (1.0 - n as f64 * eps)
}

pub(super) fn intersect_triangle_f64(
    p0: Vec3A,
    p1: Vec3A,
    p2: Vec3A,
    ray: &Ray,
) -> Option<ShapeHit> {
    let (o, dir) = (ray.o.as_dvec3(), ray.d.as_dvec3());
    let ad = dir.abs();
    let kz = if ad.x > ad.y {
        if ad.x > ad.z { 0 } else { 2 }
    } else if ad.y > ad.z {
        1
    } else {
        2
    };
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let permute = |v: DVec3| DVec3::new(v[kx], v[ky], v[kz]);
    let d = permute(dir);
    let (sx, sy, sz) = (-d.x / d.z, -d.y / d.z, 1.0 / d.z);
    let shear = |p: Vec3A| {
        let q = permute(p.as_dvec3() - o);
        DVec3::new(q.x + sx * q.z, q.y + sy * q.z, q.z * sz)
    };
    let (a, b, c) = (shear(p0), shear(p1), shear(p2));
    let e0 = b.x * c.y - b.y * c.x;
    let e1 = c.x * a.y - c.y * a.x;
    let e2 = a.x * b.y - a.y * b.x;
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    let t = (e0 * a.z + e1 * b.z + e2 * c.z) / det;
    if !(t > 0.0 && t <= ray.t_max as f64) {
        return None;
    }
    // pbrt-v4's bound, in f64 (the inputs are exact: f32 values widened).
    let max_zt = a.z.abs().max(b.z.abs()).max(c.z.abs());
    let delta_z = gamma64(3) * max_zt;
    let max_xt = a.x.abs().max(b.x.abs()).max(c.x.abs());
    let max_yt = a.y.abs().max(b.y.abs()).max(c.y.abs());
    let delta_x = gamma64(5) * (max_xt + max_zt);
    let delta_y = gamma64(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma64(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma64(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) / det.abs();
    (t > delta_t && (t as f32) > 0.0).then(|| ShapeHit {
        t: t as f32,
        uv: [(e1 / det) as f32, (e2 / det) as f32],
    })
}
