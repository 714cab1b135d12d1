//! Uniform sampling of the solid angle a rectangle subtends from a point (Ureña, Fajardo and
//! King, "An Area-Preserving Parametrization for Spherical Rectangles", EGSR 2013).
//!
//! Sampling a rectangular light by area weighs a sample by cos / distance^2, which has no
//! bound as the receiver comes close: a wall 2 cm from a quad light facing it gets estimates
//! thousands of times their mean, and a final gather that lands there turns them into
//! fireflies all over the room. By solid angle the weight is the solid angle itself, at most
//! 2 pi. Computed in f64: the solid angle is a difference of angles that cancels for a far
//! rectangle.

use std::f64::consts::PI;

use glam::{DVec3, Vec2, Vec3A};

use crate::render::light::{Light, LightSample};

/// A rectangle as seen from a point, ready to be sampled.
pub struct SphericalRect {
    origin: DVec3,
    /// The rectangle's frame: x and y along its edges, z toward the origin's far side.
    x: DVec3,
    y: DVec3,
    z: DVec3,
    z0: f64,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    b0: f64,
    b1: f64,
    k: f64,
    solid_angle: f64,
}

impl SphericalRect {
    /// The rectangle with corner `corner` and perpendicular edges `edge_u`, `edge_v`, seen from
    /// `origin`; None when the origin lies in its plane or the solid angle is too small to
    /// sample this way (then area sampling is as good).
    pub fn new(origin: Vec3A, corner: Vec3A, edge_u: Vec3A, edge_v: Vec3A) -> Option<Self> {
        let (o, s) = (origin.as_dvec3(), corner.as_dvec3());
        let (eu, ev) = (edge_u.as_dvec3(), edge_v.as_dvec3());
        let (lu, lv) = (eu.length(), ev.length());
        let (x, y) = (eu / lu, ev / lv);
        let mut z = x.cross(y);
        let d = s - o;
        let mut z0 = d.dot(z);
        if z0 > 0.0 {
            z = -z;
            z0 = -z0;
        }
        let (x0, y0) = (d.dot(x), d.dot(y));
        let (x1, y1) = (x0 + lu, y0 + lv);
        // The normals of the four planes through the origin and each edge.
        let n0 = DVec3::new(0.0, z0, -y0).normalize();
        let n1 = DVec3::new(-z0, 0.0, x1).normalize();
        let n2 = DVec3::new(0.0, -z0, y1).normalize();
        let n3 = DVec3::new(z0, 0.0, -x0).normalize();
        let angle = |a: DVec3, b: DVec3| (-a.dot(b)).clamp(-1.0, 1.0).acos();
        let (g0, g1) = (angle(n0, n1), angle(n1, n2));
        let (g2, g3) = (angle(n2, n3), angle(n3, n0));
        let k = 2.0 * PI - g2 - g3;
        let solid_angle = g0 + g1 - k;
        let usable = z0 < 0.0 && solid_angle > 1e-6 && solid_angle.is_finite();
        usable.then_some(SphericalRect {
            origin: o,
            x,
            y,
            z,
            z0,
            x0,
            x1,
            y0,
            y1,
            b0: n0.z,
            b1: n2.z,
            k,
            solid_angle,
        })
    }

    /// The solid angle the rectangle subtends: the weight of each sample.
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle as f32
    }

    /// The point of the rectangle seen in direction u of the solid angle, uniformly.
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let (u, v) = (u.x as f64, u.y as f64);
        let b0sq = self.b0 * self.b0;
        let au = u * self.solid_angle + self.k;
        let fu = (au.cos() * self.b0 - self.b1) / au.sin();
        let cu = ((fu * fu + b0sq).sqrt().recip().copysign(fu)).clamp(-1.0, 1.0);
        let xu = (-(cu * self.z0) / (1.0 - cu * cu).max(0.0).sqrt()).clamp(self.x0, self.x1);
        let d2 = xu * xu + self.z0 * self.z0;
        let h0 = self.y0 / (d2 + self.y0 * self.y0).sqrt();
        let h1 = self.y1 / (d2 + self.y1 * self.y1).sqrt();
        let hv = h0 + v * (h1 - h0);
        let yv = if hv * hv < 1.0 - 1e-12 {
            (hv * d2.sqrt() / (1.0 - hv * hv).sqrt()).clamp(self.y0, self.y1)
        } else {
            self.y1
        };
        Vec3A::from((self.origin + xu * self.x + yv * self.y + self.z0 * self.z).as_vec3())
    }
}

/// Within how many times its squared diagonal of a quad light's centre shadow rays sample
/// it by solid angle (the diagonal, not the area, so that a long thin light is close
/// wherever it is long): a square's two side lengths, from where area samples' weights
/// span about 5x (cos / distance^2 over the quad), further away less.
const CLOSE: f32 = 2.0;

impl Light {
    /// [`Light::sample_li`] for the camera pass's shadow rays, which no other technique
    /// weighs against: a rectangular quad light close to the receiver (its centre within
    /// [`CLOSE`] squared diagonals) by the solid angle it subtends, whose weight stays
    /// bounded however close; any other light, and a far quad, whose area samples' weights
    /// differ little, as `sample_li` samples it. That is cheaper: by solid angle everywhere,
    /// a ppm render with gathering on cornell took 19% more time, near the quad only 1%.
    /// The bidirectional integrators keep sampling quads by area, the density their MIS
    /// weights are written for.
    pub fn sample_li_by_solid_angle(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        if let Light::Quad {
            corner,
            edge_u,
            edge_v,
            n,
            radiance,
            prim,
            ..
        } = *self
            && (p - (corner + 0.5 * (edge_u + edge_v))).length_squared()
                < CLOSE * (edge_u + edge_v).length_squared()
            && edge_u.dot(edge_v).abs() <= 1e-4 * edge_u.length() * edge_v.length()
        {
            // The quad emits toward n only: nothing to sample behind it, and no solid angle
            // (f64 and four arc cosines) to compute.
            if n.dot(p - corner) <= 0.0 {
                return None;
            }
            // A solid angle too small to sample this way (a receiver grazing the quad's
            // plane) falls through to area sampling.
            if let Some(rect) = SphericalRect::new(p, corner, edge_u, edge_v) {
                let q = rect.sample(u);
                let d = q - p;
                let dist = d.length();
                return (dist > 0.0).then(|| LightSample {
                    wi: d / dist,
                    target: q,
                    prim,
                    li_over_pdf: radiance * rect.solid_angle(),
                });
            }
        }
        self.sample_li(p, u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solid angle of a square seen from above its centre has a closed form
    /// (4 asin(a^2 / (a^2 + 4 h^2)) for side a at height h), and every sample lies on the
    /// square, spread evenly over the solid angle: the mean direction's cosine about the
    /// axis matches the integral's.
    #[test]
    fn a_square_s_solid_angle_and_samples_match_the_closed_form() {
        let (a, h) = (2.0f32, 0.5f32);
        let corner = Vec3A::new(-1.0, -1.0, 0.0);
        let (eu, ev) = (Vec3A::new(a, 0.0, 0.0), Vec3A::new(0.0, a, 0.0));
        let o = Vec3A::new(0.0, 0.0, h);
        let r = SphericalRect::new(o, corner, eu, ev).unwrap();
        let exact = 4.0 * (a * a / (a * a + 4.0 * h * h)).asin();
        assert!(
            (r.solid_angle() - exact).abs() < 1e-5,
            "{}",
            r.solid_angle()
        );
        // The mean over the solid angle of cos(theta) is the projected solid angle over
        // the solid angle; for a square, the projected solid angle is 4 (the unit
        // sphere's form factor, pi F) by the closed form of a rectangle's form factor.
        let n = 256;
        let mut cos_sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let p = r.sample(u);
                assert!(p.z.abs() < 1e-5 && p.x.abs() <= 1.0 + 1e-5 && p.y.abs() <= 1.0 + 1e-5);
                cos_sum += ((o - p).normalize().z) as f64;
            }
        }
        let projected = cos_sum / (n * n) as f64 * r.solid_angle() as f64;
        let expected = square_projected_solid_angle(a as f64, h as f64);
        assert!(
            (projected / expected - 1.0).abs() < 1e-3,
            "{projected} vs {expected}"
        );
    }

    /// pi times the form factor from a point to a parallel square centred above it (side a,
    /// height h): four times that of a rectangle of sides a/2 with a corner under the point.
    fn square_projected_solid_angle(a: f64, h: f64) -> f64 {
        let (x, y) = (a / 2.0 / h, a / 2.0 / h);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        let quarter = 0.5 * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan());
        4.0 * quarter
    }

    /// A square light 2 cm above a receiver, facing it: the irradiance by solid-angle
    /// samples matches the closed form, every sample's weight stays within 2 pi L (by area
    /// it reaches L A / d^2, 40,000 L here), and a far or skewed quad is sampled by area.
    #[test]
    fn a_close_quad_light_s_samples_are_bounded_and_unbiased() {
        let (a, h) = (2.0f32, 0.02f32);
        // As the scene builds a quad light: its normal and area from its edges.
        let quad = |corner: Vec3A, edge_u: Vec3A, edge_v: Vec3A| {
            let c = edge_u.cross(edge_v);
            Light::Quad {
                corner,
                edge_u,
                edge_v,
                n: c.normalize(),
                area: c.length(),
                radiance: crate::render::math::Rgb::splat(1.0),
                prim: 0,
            }
        };
        // Facing -z, toward the receiver at the origin.
        let square =
            |edge_v: Vec3A| quad(Vec3A::new(-1.0, -1.0, h), Vec3A::new(0.0, a, 0.0), edge_v);
        let light = square(Vec3A::new(a, 0.0, 0.0));
        let n = 64;
        let (mut e, mut max) = (0.0f64, 0.0f32);
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let ls = light.sample_li_by_solid_angle(Vec3A::ZERO, u).unwrap();
                let w = ls.li_over_pdf.x * ls.wi.z;
                e += w as f64;
                max = max.max(ls.li_over_pdf.x);
            }
        }
        let e = e / (n * n) as f64;
        let expected = square_projected_solid_angle(a as f64, h as f64);
        assert!((e / expected - 1.0).abs() < 1e-3, "{e} vs {expected}");
        assert!(max <= 2.0 * std::f32::consts::PI + 1e-4, "{max}");
        let u = Vec2::new(0.3, 0.6);
        let far = Vec3A::new(0.0, 0.0, -10.0);
        let by_area = light.sample_li(far, u).map(|ls| ls.target);
        assert_eq!(
            light.sample_li_by_solid_angle(far, u).map(|ls| ls.target),
            by_area
        );
        // A strip 20 long and 0.1 wide, seen from 5 off its centre along it: far in widths
        // (and areas), close in lengths.
        let strip = quad(
            Vec3A::new(-10.0, -0.05, 1.0),
            Vec3A::new(0.0, 0.1, 0.0),
            Vec3A::new(20.0, 0.0, 0.0),
        );
        let near_end = Vec3A::new(5.0, 0.0, 0.0);
        let by_area = strip.sample_li(near_end, u).map(|ls| ls.target);
        assert_ne!(
            strip
                .sample_li_by_solid_angle(near_end, u)
                .map(|ls| ls.target),
            by_area
        );
        let skewed = square(Vec3A::new(a, 0.5, 0.0));
        let by_area = skewed.sample_li(Vec3A::ZERO, u).map(|ls| ls.target);
        let ls = skewed.sample_li_by_solid_angle(Vec3A::ZERO, u);
        assert_eq!(ls.map(|ls| ls.target), by_area);
    }

    /// From the rectangle's plane nothing is sampled this way.
    #[test]
    fn no_solid_angle_from_the_rectangle_s_plane() {
        let corner = Vec3A::new(-1.0, -1.0, 0.0);
        let (eu, ev) = (Vec3A::new(2.0, 0.0, 0.0), Vec3A::new(0.0, 2.0, 0.0));
        assert!(SphericalRect::new(Vec3A::new(3.0, 0.0, 0.0), corner, eu, ev).is_none());
    }
}
