//! The closed set of lights: sampling toward a receiving point (shadow rays) and sampling
//! emitted photons.
//!
//! Units: a point light's `power` is total flux (W) and its intensity power / (4 pi); area
//! lights give radiance, so a sphere light emits pi L 4 pi r^2 and a quad light pi L A.

use std::f32::consts::PI;

use glam::{Vec2, Vec3A};

use crate::render::geometry::{NO_PRIM, PrimId, Ray, SurfacePoint, spawn_ray};
use crate::render::math::{Frame, Rgb, gamma, luminance};
use crate::render::sampling::{cosine_hemisphere, uniform_cone, uniform_sphere};

#[derive(Clone, Copy, Debug)]
pub enum Light {
    /// Isotropic point light, invisible to the camera.
    Point { position: Vec3A, power: Rgb },
    /// Emits `radiance` outward from its whole surface; its primitive is `prim`.
    Sphere {
        center: Vec3A,
        radius: f32,
        radiance: Rgb,
        prim: PrimId,
    },
    /// Emits `radiance` on the side of `n` = normalize(cross(edge_u, edge_v)) only.
    Quad {
        corner: Vec3A,
        edge_u: Vec3A,
        edge_v: Vec3A,
        n: Vec3A,
        area: f32,
        radiance: Rgb,
        prim: PrimId,
    },
}

/// A direction toward a light from a receiving point. The light's contribution to reflected
/// radiance is f(wo, wi) |cos(n, wi)| * `li_over_pdf`.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub wi: Vec3A,
    /// The sampled point on the light, and its primitive (NO_PRIM for point lights).
    pub target: Vec3A,
    pub prim: PrimId,
    pub li_over_pdf: Rgb,
}

/// An emitted photon: its first ray and the flux it carries per unit of selection
/// probability (divide by the photon count and the light-selection probability).
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    pub ray: Ray,
    pub flux: Rgb,
}

impl Light {
    /// Total emitted flux (W per channel).
    pub fn power(&self) -> Rgb {
        match *self {
            Light::Point { power, .. } => power,
            Light::Sphere {
                radius, radiance, ..
            } => radiance * (PI * 4.0 * PI * radius * radius),
            Light::Quad { area, radiance, .. } => radiance * (PI * area),
        }
    }

    /// A light at a single point (a delta in position): only connections and light
    /// tracing reach it, never a camera path.
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. })
    }

    pub fn prim(&self) -> PrimId {
        match *self {
            Light::Point { .. } => NO_PRIM,
            Light::Sphere { prim, .. } | Light::Quad { prim, .. } => prim,
        }
    }

    /// Radiance leaving the light's surface at a point with outward normal `n` toward `wo`.
    pub fn emitted(&self, n: Vec3A, wo: Vec3A) -> Rgb {
        match *self {
            Light::Point { .. } => Rgb::ZERO,
            Light::Sphere { radiance, .. } | Light::Quad { radiance, .. } => {
                if n.dot(wo) > 0.0 {
                    radiance
                } else {
                    Rgb::ZERO
                }
            }
        }
    }

    /// Sample incident light at `p`: point lights exactly, quads by area, spheres uniformly
    /// over the cone they subtend (pbrt-v4 6.2.4). None if the sample cannot carry light.
    pub fn sample_li(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        match *self {
            Light::Point { position, power } => {
                let d = position - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                Some(LightSample {
                    wi: d / dist2.sqrt(),
                    target: position,
                    prim: NO_PRIM,
                    li_over_pdf: power / (4.0 * PI * dist2),
                })
            }
            Light::Quad {
                corner,
                edge_u,
                edge_v,
                n,
                area,
                radiance,
                prim,
            } => {
                let q = corner + u.x * edge_u + u.y * edge_v;
                let d = q - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let cos_l = -n.dot(wi);
                (cos_l > 0.0).then(|| LightSample {
                    wi,
                    target: q,
                    prim,
                    li_over_pdf: radiance * (cos_l * area / dist2),
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
                prim,
            } => {
                let to_c = center - p;
                let dc2 = to_c.length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 {
                    return None;
                }
                let dc = dc2.sqrt();
                let sin2_max = r2 / dc2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                let one_minus_cos_max = sin2_max / (1.0 + cos_max);
                let local = uniform_cone(u, one_minus_cos_max);
                let axis = to_c / dc;
                let wi = Frame::from_normal(axis).to_world(local);
                // Distance to the near side of the sphere along wi.
                let cos_t = local.z;
                let sin2_t = (1.0 - cos_t * cos_t).max(0.0);
                let t = dc * cos_t - (r2 - dc2 * sin2_t).max(0.0).sqrt();
                Some(LightSample {
                    wi,
                    target: p + wi * t,
                    prim,
                    li_over_pdf: radiance * (2.0 * PI * one_minus_cos_max),
                })
            }
        }
    }

    /// Where a photon leaves the light: a point light's position, or a uniform point on an
    /// area light's surface with the normal it emits around.
    pub fn emission_origin(&self, u_pos: Vec2) -> EmissionOrigin {
        match *self {
            Light::Point { position, .. } => EmissionOrigin {
                sp: SurfacePoint {
                    p: position,
                    p_error: Vec3A::ZERO,
                    n: Vec3A::ZERO,
                    prim: NO_PRIM,
                },
                normal: None,
            },
            Light::Sphere {
                center,
                radius,
                prim,
                ..
            } => {
                let n = uniform_sphere(u_pos);
                let local = n * radius;
                let p = center + local;
                EmissionOrigin {
                    sp: SurfacePoint {
                        p,
                        p_error: gamma(5) * local.abs() + gamma(1) * p.abs(),
                        n,
                        prim,
                    },
                    normal: Some(n),
                }
            }
            Light::Quad {
                corner,
                edge_u,
                edge_v,
                n,
                prim,
                ..
            } => {
                let (a, b) = (u_pos.x * edge_u, u_pos.y * edge_v);
                EmissionOrigin {
                    sp: SurfacePoint {
                        p: corner + a + b,
                        p_error: gamma(4) * (corner.abs() + a.abs() + b.abs()),
                        n,
                        prim,
                    },
                    normal: Some(n),
                }
            }
        }
    }

    /// Emit a photon: point lights uniformly over the sphere of directions (as the seed did),
    /// area lights from a uniform point on their surface, cosine-weighted about the normal.
    pub fn sample_emission(&self, u_pos: Vec2, u_dir: Vec2) -> Emission {
        let origin = self.emission_origin(u_pos);
        let dir = match origin.normal {
            None => uniform_sphere(u_dir),
            Some(n) => Frame::from_normal(n).to_world(cosine_hemisphere(u_dir)),
        };
        Emission {
            ray: origin.ray(dir),
            flux: self.power(),
        }
    }
}

/// Light-selection table: cumulative luminance of the lights' power, dark lights left out.
/// Photons and light subpaths pick their light by it, and a bidirectional path's weights
/// need the same probabilities.
pub(crate) struct LightPicker {
    cdf: Vec<f32>,
    pub(crate) total: f32,
}

impl LightPicker {
    pub(crate) fn new(lights: &[Light], dark: &[u32]) -> LightPicker {
        let mut cdf = Vec::with_capacity(lights.len());
        let mut acc = 0.0;
        for (i, l) in lights.iter().enumerate() {
            if !dark.contains(&(i as u32)) {
                acc += luminance(l.power()).max(0.0);
            }
            cdf.push(acc);
        }
        LightPicker { cdf, total: acc }
    }

    /// The light for `u` in [0, 1) and its selection probability.
    pub(crate) fn pick(&self, u: f32) -> (usize, f32) {
        let x = u * self.total;
        // x can round up to the total: then the last light with any power (never one with
        // none, whose probability 0 would divide a photon's flux).
        let i = self.cdf.partition_point(|&c| c <= x);
        let i = if i < self.cdf.len() {
            i
        } else {
            self.cdf.partition_point(|&c| c < self.total)
        };
        (i, self.probability(i))
    }

    /// The probability of picking light `i`.
    pub(crate) fn probability(&self, i: usize) -> f32 {
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (self.cdf[i] - prev) / self.total
    }
}

/// The start of a photon path on a light.
pub struct EmissionOrigin {
    pub sp: SurfacePoint,
    /// The normal an area light emits around; `None` for a point light (every direction).
    pub normal: Option<Vec3A>,
}

impl EmissionOrigin {
    /// The light's own density of emission directions from here (per steradian): 1/(4 pi)
    /// for a point light, cos/pi about an area light's normal (0 behind it).
    pub fn direction_pdf(&self, dir: Vec3A) -> f32 {
        match self.normal {
            None => 0.25 * std::f32::consts::FRAC_1_PI,
            Some(n) => n.dot(dir).max(0.0) * std::f32::consts::FRAC_1_PI,
        }
    }

    /// The photon's first ray, along `dir` (robustly off an area light's surface).
    pub fn ray(&self, dir: Vec3A) -> Ray {
        match self.normal {
            None => Ray::new(self.sp.p, dir),
            Some(_) => spawn_ray(&self.sp, dir),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream};

    /// Irradiance below a quad light estimated with sample_li matches a dense numerical
    /// integration of L cos cos' / d^2 over the quad.
    #[test]
    fn quad_light_irradiance_matches_numeric_integration() {
        let light = Light::Quad {
            corner: Vec3A::new(-0.5, 1.0, -0.5),
            edge_u: Vec3A::new(0.0, 0.0, 1.0),
            edge_v: Vec3A::new(1.0, 0.0, 0.0),
            n: Vec3A::new(0.0, -1.0, 0.0),
            area: 1.0,
            radiance: Rgb::ONE,
            prim: 0,
        };
        let mut s = Sampler::new(3, Stream::Camera, 0);
        let n = 200_000;
        let mut e = 0.0;
        for _ in 0..n {
            if let Some(ls) = light.sample_li(Vec3A::ZERO, s.next_2d()) {
                e += ls.li_over_pdf.x * ls.wi.y;
            }
        }
        e /= n as f32;
        // Midpoint-rule integral of L cos(theta) cos(theta_l) / d^2 over the unit square at height 1.
        let m = 400;
        let mut exact = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let x = -0.5 + (i as f64 + 0.5) / m as f64;
                let z = -0.5 + (j as f64 + 0.5) / m as f64;
                let d2 = x * x + 1.0 + z * z;
                exact += 1.0 / (d2 * d2) / (m * m) as f64;
            }
        }
        assert!((e as f64 / exact - 1.0).abs() < 0.01, "{e} vs {exact}");
    }

    #[test]
    fn sphere_light_irradiance_matches_analytic() {
        // E = pi L (r/d)^2 for a sphere light straight above the receiver.
        let light = Light::Sphere {
            center: Vec3A::new(0.0, 2.0, 0.0),
            radius: 0.25,
            radiance: Rgb::ONE,
            prim: 0,
        };
        let mut s = Sampler::new(4, Stream::Camera, 0);
        let n = 200_000;
        let mut e = 0.0f64;
        for _ in 0..n {
            let ls = light.sample_li(Vec3A::ZERO, s.next_2d()).unwrap();
            e += (ls.li_over_pdf.x * ls.wi.y) as f64;
            assert!(((ls.target - Vec3A::new(0.0, 2.0, 0.0)).length() - 0.25).abs() < 1e-4);
        }
        e /= n as f64;
        let exact = PI as f64 * (0.25f64 / 2.0).powi(2);
        assert!((e / exact - 1.0).abs() < 0.005, "{e} vs {exact}");
    }
}
