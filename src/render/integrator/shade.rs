//! The camera pass: radiance along a camera ray, following the plan of `integrator/mod.rs`.

use std::f32::consts::FRAC_1_PI;

use super::{Plan, VertexPlan};
use crate::render::geometry::{Hit, Ray, Surface, SurfacePoint, spawn_ray, spawn_ray_to};
use crate::render::material::{Material, SpecularBranch, Transport};
use crate::render::math::{Frame, Rgb, luminance, reflect};
use crate::render::photon::{CausticLookup, IrradianceCache, KnnScratch};
use crate::render::sampling::{Sampler, cosine_hemisphere, power_cosine};
use crate::render::scene::Scene;

/// Camera paths split into both branches at glass (Whitted 1980) for their first
/// SPLIT_DEPTH specular bounces: the reflection on a glass surface and what is seen through
/// it are both smooth. Deeper, and on gather and glossy rays, one branch is chosen at random
/// in proportion to its weight (unbiased, and cheap where it matters less).
const SPLIT_DEPTH: u32 = 2;

/// Read-only state of a camera pass, shared by all threads.
pub struct Shader<'a> {
    pub scene: &'a Scene,
    pub plan: Plan,
    pub caustic: Option<CausticLookup<'a>>,
    pub global: Option<&'a IrradianceCache>,
    pub gather_rays: u32,
    pub max_depth: u32,
}

/// Per-thread scratch memory.
#[derive(Default)]
pub struct Scratch {
    knn: KnnScratch,
    /// The last irradiance point found (a search hint; results do not depend on it).
    global_hint: Option<u32>,
}

impl Shader<'_> {
    /// Radiance arriving at the camera along `ray`.
    pub fn camera_ray(&self, ray: &Ray, s: &mut Sampler, scratch: &mut Scratch) -> Rgb {
        self.trace(ray, 0, true, &self.plan.primary, s, scratch)
    }

    /// Radiance along `ray`; `count_emission` says whether light surfaces seen directly count
    /// (they do not when shadow rays already sampled them), `vertex` how to shade the first
    /// non-specular vertex.
    fn trace(
        &self,
        ray: &Ray,
        depth: u32,
        count_emission: bool,
        vertex: &VertexPlan,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let Some(hit) = self.scene.intersect(ray) else {
            return Rgb::ZERO;
        };
        let wo = -ray.d;
        match self.scene.surface(hit.point.prim) {
            Surface::Light(li) => {
                if count_emission {
                    self.scene.lights[li as usize].emitted(hit.point.n, wo)
                } else {
                    Rgb::ZERO
                }
            }
            Surface::Material(mi) => {
                let m = &self.scene.materials[mi as usize];
                if m.is_specular() {
                    self.specular(m, &hit, wo, depth, count_emission, vertex, s, scratch)
                } else {
                    self.non_specular(m, &hit.point, wo, depth, vertex, s, scratch)
                }
            }
        }
    }

    /// Follow mirror and glass: both branches near the camera, one further down.
    #[allow(clippy::too_many_arguments)]
    fn specular(
        &self,
        m: &Material,
        hit: &Hit,
        wo: glam::Vec3A,
        depth: u32,
        count_emission: bool,
        vertex: &VertexPlan,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        if depth + 1 >= self.max_depth {
            return Rgb::ZERO;
        }
        let b = m.specular_branches(wo, hit.point.n, Transport::Radiance);
        let mut follow = |br: SpecularBranch, scale: f32, s: &mut Sampler| {
            let ray = spawn_ray(&hit.point, br.wi);
            br.weight * scale * self.trace(&ray, depth + 1, count_emission, vertex, s, scratch)
        };
        // Split only on the camera's own specular chain; gather and glossy rays pick one branch.
        let split = depth < SPLIT_DEPTH && std::ptr::eq(vertex, &self.plan.primary);
        match (b.reflection, b.transmission) {
            (Some(r), Some(t)) if split => follow(r, 1.0, s) + follow(t, 1.0, s),
            (Some(r), Some(t)) => {
                let (lr, lt) = (luminance(r.weight), luminance(t.weight));
                let pr = lr / (lr + lt);
                if s.next_f32() < pr {
                    follow(r, 1.0 / pr, s)
                } else {
                    follow(t, 1.0 / (1.0 - pr), s)
                }
            }
            (Some(x), None) | (None, Some(x)) => follow(x, 1.0, s),
            (None, None) => Rgb::ZERO,
        }
    }

    /// Radiance leaving a non-specular point toward `wo`, estimated as `vertex` says.
    #[allow(clippy::too_many_arguments)]
    fn non_specular(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: glam::Vec3A,
        depth: u32,
        vertex: &VertexPlan,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let n_side = if sp.n.dot(wo) < 0.0 { -sp.n } else { sp.n };
        let rho = m.diffuse_reflectance();
        let mut l = Rgb::ZERO;
        if vertex.shadow_rays {
            l += self.direct_light(m, sp, wo, s);
        }
        if rho != Rgb::ZERO {
            if vertex.caustic_map
                && let Some(cm) = &self.caustic
            {
                l += rho * FRAC_1_PI * cm.irradiance(sp.p, n_side, &mut scratch.knn);
            }
            if !vertex.global.is_empty()
                && let Some(cache) = self.global
            {
                l += rho
                    * FRAC_1_PI
                    * cache.lookup(sp.p, n_side, vertex.global, &mut scratch.global_hint);
            }
            if vertex.gather {
                l += rho * self.final_gather(sp, n_side, depth, s, scratch);
            }
        }
        if vertex.glossy_rays
            && depth + 1 < self.max_depth
            && let Material::Phong {
                specular, exponent, ..
            } = *m
            && specular != Rgb::ZERO
        {
            // Sample the glossy lobe alone: f_s cos / pdf = ks (e + 2) / (e + 1) cos(theta_i).
            let r = reflect(wo, n_side);
            let wi = Frame::from_normal(r).to_world(power_cosine(s.next_2d(), exponent));
            let cos = wi.dot(n_side);
            if cos > 0.0 {
                let weight = specular * ((exponent + 2.0) / (exponent + 1.0) * cos);
                let ray = spawn_ray(sp, wi);
                let count_emission = !vertex.shadow_rays;
                l += weight
                    * self.trace(
                        &ray,
                        depth + 1,
                        count_emission,
                        &self.plan.secondary,
                        s,
                        scratch,
                    );
            }
        }
        l
    }

    /// Direct light by one shadow ray per light (Jensen 2001, section 9.1.1).
    fn direct_light(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: glam::Vec3A,
        s: &mut Sampler,
    ) -> Rgb {
        let mut l = Rgb::ZERO;
        for light in &self.scene.lights {
            let u = s.next_2d();
            let Some(ls) = light.sample_li(sp.p, u) else {
                continue;
            };
            let f = m.eval(wo, ls.wi, sp.n);
            if f == Rgb::ZERO || ls.li_over_pdf == Rgb::ZERO {
                continue;
            }
            let Some((ray, wi, _)) = spawn_ray_to(sp, ls.target, ls.prim) else {
                continue;
            };
            if !self.scene.occluded(&ray) {
                l += f * wi.dot(sp.n).abs() * ls.li_over_pdf;
            }
        }
        l
    }

    /// Final gathering (Jensen 2001, section 9.1.4): the mean radiance over cosine-sampled
    /// directions of the hemisphere, read at the first non-specular hit of each gather ray.
    /// Multiplied by rho this is the indirect diffuse radiance at the point.
    fn final_gather(
        &self,
        sp: &SurfacePoint,
        n_side: glam::Vec3A,
        depth: u32,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let frame = Frame::from_normal(n_side);
        let g = self.gather_rays;
        let mut sum = Rgb::ZERO;
        for _ in 0..g {
            let wi = frame.to_world(cosine_hemisphere(s.next_2d()));
            let ray = spawn_ray(sp, wi);
            sum += self.trace(&ray, depth + 1, false, &self.plan.gather_hit, s, scratch);
        }
        sum / g as f32
    }
}
