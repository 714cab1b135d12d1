//! A glass sphere's light in closed form, up to one-dimensional quadratures: a ray and the
//! sphere's centre span a plane that every reflection and refraction keeps the ray in, so a
//! two-dimensional trace follows each ray through every internal bounce, each interface
//! weighted by the exact Fresnel reflectance (`fresnel`, written independently of the
//! renderer's).

use glam::DVec2;

use super::fresnel;

/// A ray leaving the sphere for good (or missing it): from where, which way, and the share of
/// the incoming ray's power it carries.
pub struct Exit {
    pub p: DVec2,
    pub dir: DVec2,
    pub w: f64,
}

/// Every ray that leaves a sphere of radius `r` and index `ior`, centred at the origin, when
/// a ray from (0, d) heads down at `alpha` from the -y axis: the outer reflection and each
/// refraction out after 0, 1, 2, ... internal reflections, up to 64 of them or until less
/// than 1e-12 of the power is left inside (a ray that enters near grazing keeps nearly all of
/// it for thousands of reflections, but carries almost none: the cap moves the tests' figures
/// by about 1e-7). The point and direction are put back on the sphere and to unit length at
/// every bounce: without that, rounding grows about twentyfold a bounce near the axis. A ray
/// that misses is its own exit.
pub fn exits(d: f64, r: f64, ior: f64, alpha: f64) -> Vec<Exit> {
    let o = DVec2::new(0.0, d);
    let dir = DVec2::new(alpha.sin(), -alpha.cos());
    let b = o.dot(dir);
    let c = o.length_squared() - r * r;
    if b * b - c <= 0.0 || b > 0.0 {
        return vec![Exit { p: o, dir, w: 1.0 }];
    }
    let mut p = o + dir * (-b - (b * b - c).sqrt());
    let n = p / r;
    let cos_i = -dir.dot(n);
    let f = fresnel(cos_i, 1.0, ior);
    let mut out = vec![Exit {
        p,
        dir: dir + 2.0 * cos_i * n,
        w: f,
    }];
    let eta = 1.0 / ior;
    let cos_t = (1.0 - eta * eta * (1.0 - cos_i * cos_i)).sqrt();
    let mut inner = (eta * dir + (eta * cos_i - cos_t) * n).normalize();
    let mut w = 1.0 - f;
    for _ in 0..64 {
        // The chord to the next interface.
        p += inner * (-2.0 * p.dot(inner));
        p = p.normalize() * r;
        let n_out = p / r;
        let cos_in = inner.dot(n_out);
        let f_in = fresnel(cos_in, ior, 1.0);
        if f_in < 1.0 {
            let cos_out = (1.0 - ior * ior * (1.0 - cos_in * cos_in)).sqrt();
            out.push(Exit {
                p,
                dir: (ior * inner + (cos_out - ior * cos_in) * n_out).normalize(),
                w: w * (1.0 - f_in),
            });
        }
        w *= f_in;
        inner = (inner - 2.0 * cos_in * n_out).normalize();
        if w < 1e-12 {
            break;
        }
    }
    out
}

/// Where an exit meets the plane y = `y0` below it (its signed x), if it heads down.
pub fn landing_x(e: &Exit, y0: f64) -> Option<f64> {
    (e.dir.y < 0.0).then(|| e.p.x + (y0 - e.p.y) / e.dir.y * e.dir.x)
}

/// The share of a circle of radius `rho` about a square's centre that lies inside the square
/// (half-width `s`): the ring of points a ray lands on as the plane of its trace turns about
/// the axis.
pub fn share_of_circle_in_square(rho: f64, s: f64) -> f64 {
    if rho <= s {
        1.0
    } else if rho >= s * std::f64::consts::SQRT_2 {
        0.0
    } else {
        1.0 - 4.0 / std::f64::consts::PI * (s / rho).acos()
    }
}
