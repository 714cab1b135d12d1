//! The closed set of materials and their BSDFs.
//!
//! Conventions (pbrt-v4 chapter 9): `wo` points away from the surface toward the viewer (or
//! the previous photon vertex), `wi` away from the surface toward where light comes from,
//! both unit; `n` is the geometric normal. Diffuse, mirror and Phong are two-sided; a
//! dielectric's inside is the side opposite its normal.

use std::f32::consts::{FRAC_1_PI, TAU};

use glam::{Vec2, Vec3A};

use crate::render::math::{Frame, Rgb, luminance, reflect};
use crate::render::sampling::{
    cosine_hemisphere, cosine_hemisphere_pdf, power_cosine, power_cosine_pdf,
};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Lambertian: f = albedo / pi.
    Diffuse { albedo: Rgb },
    /// Perfect specular reflection scaled by `reflectance`.
    Mirror { reflectance: Rgb },
    /// Smooth glass with exact unpolarized Fresnel; outside index 1.
    Dielectric { ior: f32 },
    /// Energy-conserving modified Phong (Lafortune and Willems 1994, "Using the modified
    /// Phong reflectance model for physically based rendering"):
    /// f = kd/pi + ks (e + 2)/(2 pi) cos^e(alpha), alpha between wi and the mirror direction.
    /// Conserves energy when kd + ks <= 1 (enforced by the scene loader).
    Phong {
        diffuse: Rgb,
        specular: Rgb,
        exponent: f32,
    },
}

/// Which quantity a path carries (Veach 1997, section 5.2): camera paths carry radiance,
/// which is scaled by 1/eta^2 on refraction; photons carry flux (importance), which is not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    Radiance,
    Importance,
}

/// A sampled incident direction. `weight` is f |cos| / pdf, the throughput multiplier.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3A,
    pub weight: Rgb,
    /// Solid-angle density; 0 for specular (delta) samples.
    pub pdf: f32,
    pub specular: bool,
}

/// Unpolarized Fresnel reflectance of a smooth dielectric interface (Born and Wolf;
/// pbrt-v4 9.3.6). `cos_i` is the cosine on the incident side, `eta` = n_t / n_i.
/// Returns 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    if eta == 1.0 {
        return 0.0;
    }
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    ((r_parl * r_parl + r_perp * r_perp) * 0.5).clamp(0.0, 1.0)
}

/// Refraction of `wo` through a surface with unit normal `n` on wo's side; `eta` = n_t / n_i.
/// None under total internal reflection.
pub fn refract(wo: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
    if eta == 1.0 {
        return Some(-wo);
    }
    let cos_i = n.dot(wo);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / eta + (cos_i / eta - cos_t) * n).normalize())
}

/// One branch of a specular interaction: the direction and its throughput weight.
#[derive(Clone, Copy, Debug)]
pub struct SpecularBranch {
    pub wi: Vec3A,
    pub weight: Rgb,
}

/// The (at most two) branches of a specular interaction.
#[derive(Clone, Copy, Debug)]
pub struct SpecularBranches {
    pub reflection: Option<SpecularBranch>,
    pub transmission: Option<SpecularBranch>,
}

impl Material {
    /// Mirror and glass scatter only into discrete directions (delta BSDFs).
    pub fn is_specular(&self) -> bool {
        matches!(self, Material::Mirror { .. } | Material::Dielectric { .. })
    }

    /// The Lambertian part's reflectance (f_D = rho/pi): what photon-map estimates use.
    pub fn diffuse_reflectance(&self) -> Rgb {
        match *self {
            Material::Diffuse { albedo } => albedo,
            Material::Phong { diffuse, .. } => diffuse,
            _ => Rgb::ZERO,
        }
    }

    /// The BSDF value f(wo, wi) of the non-delta materials; zero for mirror and glass.
    pub fn eval(&self, wo: Vec3A, wi: Vec3A, n: Vec3A) -> Rgb {
        let nf = if wo.dot(n) < 0.0 { -n } else { n };
        if wi.dot(nf) <= 0.0 {
            return Rgb::ZERO;
        }
        match *self {
            Material::Diffuse { albedo } => albedo * FRAC_1_PI,
            Material::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                // The lobe lives where cos(alpha) > 0 (the hemisphere around the mirror
                // direction that the sampler covers; matters for exponent 0, where 0^0 = 1).
                let cos_a = reflect(wo, nf).dot(wi);
                let lobe = if cos_a > 0.0 {
                    (exponent + 2.0) / TAU * cos_a.powf(exponent)
                } else {
                    0.0
                };
                diffuse * FRAC_1_PI + specular * lobe
            }
            _ => Rgb::ZERO,
        }
    }

    /// Probability that [`Material::sample`] picks the glossy lobe of a Phong material.
    fn phong_specular_probability(diffuse: Rgb, specular: Rgb) -> f32 {
        let (d, s) = (luminance(diffuse), luminance(specular));
        if d + s > 0.0 { s / (d + s) } else { 0.0 }
    }

    /// Solid-angle pdf of [`Material::sample`] for the non-delta materials.
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A, n: Vec3A) -> f32 {
        let nf = if wo.dot(n) < 0.0 { -n } else { n };
        let cos = wi.dot(nf);
        if cos <= 0.0 {
            return 0.0;
        }
        match *self {
            Material::Diffuse { .. } => cosine_hemisphere_pdf(cos),
            Material::Phong {
                diffuse,
                specular,
                exponent,
            } => {
                let ps = Self::phong_specular_probability(diffuse, specular);
                let cos_a = reflect(wo, nf).dot(wi);
                (1.0 - ps) * cosine_hemisphere_pdf(cos) + ps * power_cosine_pdf(cos_a, exponent)
            }
            _ => 0.0,
        }
    }

    /// Both branches of a specular interaction, for Whitted-style splitting of camera paths.
    pub fn specular_branches(&self, wo: Vec3A, n: Vec3A, mode: Transport) -> SpecularBranches {
        match *self {
            Material::Mirror { reflectance } => {
                let nf = if wo.dot(n) < 0.0 { -n } else { n };
                SpecularBranches {
                    reflection: Some(SpecularBranch {
                        wi: reflect(wo, nf),
                        weight: reflectance,
                    }),
                    transmission: None,
                }
            }
            Material::Dielectric { ior } => {
                let cos_o = wo.dot(n);
                let entering = cos_o > 0.0;
                let (eta, nf) = if entering { (ior, n) } else { (1.0 / ior, -n) };
                let f = fresnel_dielectric(cos_o.abs(), eta);
                let reflection = (f > 0.0).then(|| SpecularBranch {
                    wi: reflect(wo, nf),
                    weight: Rgb::splat(f),
                });
                let transmission = if f < 1.0 {
                    refract(wo, nf, eta).map(|wi| {
                        let scale = match mode {
                            Transport::Radiance => 1.0 / (eta * eta),
                            Transport::Importance => 1.0,
                        };
                        SpecularBranch {
                            wi,
                            weight: Rgb::splat((1.0 - f) * scale),
                        }
                    })
                } else {
                    None
                };
                SpecularBranches {
                    reflection,
                    transmission,
                }
            }
            _ => SpecularBranches {
                reflection: None,
                transmission: None,
            },
        }
    }

    /// Sample an incident direction. `u_lobe` picks a lobe (glass: reflection with probability
    /// F; Phong: glossy with probability lum(ks)/lum(kd+ks)), `u` the direction in it.
    /// None when the sample carries no light (below the surface, or a black material).
    pub fn sample(
        &self,
        wo: Vec3A,
        n: Vec3A,
        u_lobe: f32,
        u: Vec2,
        mode: Transport,
    ) -> Option<BsdfSample> {
        match *self {
            Material::Diffuse { albedo } => Self::sample_diffuse(albedo, wo, n, u),
            Material::Mirror { .. } | Material::Dielectric { .. } => {
                self.sample_specular(wo, n, u_lobe, mode)
            }
            Material::Phong {
                diffuse,
                specular,
                exponent,
            } => self.sample_phong(
                Self::phong_specular_probability(diffuse, specular),
                exponent,
                wo,
                n,
                u_lobe,
                u,
            ),
        }
    }

    /// [`Material::sample`] of a Lambertian surface: cosine-weighted about the normal on
    /// wo's side.
    fn sample_diffuse(albedo: Rgb, wo: Vec3A, n: Vec3A, u: Vec2) -> Option<BsdfSample> {
        if albedo == Rgb::ZERO {
            return None;
        }
        let nf = if wo.dot(n) < 0.0 { -n } else { n };
        let wi = Frame::from_normal(nf).to_world(cosine_hemisphere(u));
        let cos = wi.dot(nf);
        (cos > 0.0).then_some(BsdfSample {
            wi,
            weight: albedo,
            pdf: cosine_hemisphere_pdf(cos),
            specular: false,
        })
    }

    /// [`Material::sample`] of mirror and glass: one of the [`Material::specular_branches`],
    /// reflection picked with probability F when both exist, the weight divided by that.
    fn sample_specular(
        &self,
        wo: Vec3A,
        n: Vec3A,
        u_lobe: f32,
        mode: Transport,
    ) -> Option<BsdfSample> {
        let b = self.specular_branches(wo, n, mode);
        let pr = b.reflection.map_or(0.0, |r| r.weight.x.min(1.0));
        let pick_reflection = match (b.reflection, b.transmission) {
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (Some(_), Some(_)) => u_lobe < pr,
            (None, None) => return None,
        };
        let (branch, p) = if pick_reflection {
            (
                b.reflection?,
                if b.transmission.is_some() { pr } else { 1.0 },
            )
        } else {
            (
                b.transmission?,
                if b.reflection.is_some() {
                    1.0 - pr
                } else {
                    1.0
                },
            )
        };
        Some(BsdfSample {
            wi: branch.wi,
            weight: branch.weight / p,
            pdf: 0.0,
            specular: true,
        })
    }

    /// [`Material::sample`] of Phong: the glossy lobe about the mirror direction (with
    /// probability `ps`) or the diffuse one, weighted by f cos / pdf of the mixture.
    fn sample_phong(
        &self,
        ps: f32,
        exponent: f32,
        wo: Vec3A,
        n: Vec3A,
        u_lobe: f32,
        u: Vec2,
    ) -> Option<BsdfSample> {
        let nf = if wo.dot(n) < 0.0 { -n } else { n };
        let wi = if u_lobe < ps {
            Frame::from_normal(reflect(wo, nf)).to_world(power_cosine(u, exponent))
        } else {
            Frame::from_normal(nf).to_world(cosine_hemisphere(u))
        };
        let cos = wi.dot(nf);
        if cos <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi, n);
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample {
            wi,
            weight: self.eval(wo, wi, n) * (cos / pdf),
            pdf,
            specular: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        // Normal incidence on glass 1.5: ((1.5-1)/(1.5+1))^2 = 0.04.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(0.3, 1.0), 0.0);
        // Total internal reflection beyond the critical angle from inside.
        assert_eq!(fresnel_dielectric(0.5, 1.0 / 1.5), 1.0);
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3A::Z;
        let wo = Vec3A::new(0.6, 0.0, 0.8);
        let wt = refract(wo, n, 1.5).unwrap();
        let sin_t = (1.0 - wt.z * wt.z).sqrt();
        assert!((sin_t - 0.6 / 1.5).abs() < 1e-6);
        assert!(wt.z < 0.0 && wt.x < 0.0);
    }
}
