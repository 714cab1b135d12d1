//! Direct light at a camera path's non-specular vertices, by shadow rays.

use glam::Vec3A;

use super::Shader;
use crate::render::geometry::{SurfacePoint, spawn_ray_to};
use crate::render::light::Light;
use crate::render::material::Material;
use crate::render::math::Rgb;
use crate::render::qmc::Branch;
use crate::render::sampling::Sampler;

impl Shader<'_> {
    /// Direct light by shadow rays (Jensen 2001, section 9.1.1): one to each point light,
    /// `area_rays` to each area light. With more than one, a sample's shadow rays to the area
    /// lights come from branches of its stream ([`Branch::Shadow`]), so that over a pixel's
    /// samples and passes they are one stratified set (the pixel's soft shadows and the
    /// light's extent seen from it); with one, from the sample's own stream, as every ray.
    /// The branches depend on the sample alone: where a camera path splits at glass both
    /// branches' points draw the same shadow-ray points (correlated, not biased; final
    /// gathers share their branches the same way).
    pub(super) fn direct_light(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: Vec3A,
        area_rays: u32,
        s: &mut Sampler,
    ) -> Rgb {
        if area_rays <= 1 {
            return self.one_ray_each(m, sp, wo, |_| true, s);
        }
        let mut area = Rgb::ZERO;
        for k in 0..area_rays {
            let mut b = s.branch(Branch::Shadow, k, area_rays);
            area += self.one_ray_each(m, sp, wo, |light| !light.is_delta(), &mut b);
        }
        self.one_ray_each(m, sp, wo, Light::is_delta, s) + area / area_rays as f32
    }

    /// One shadow ray to each light that `to` picks, its point on the light from `s`.
    fn one_ray_each(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: Vec3A,
        to: impl Fn(&Light) -> bool,
        s: &mut Sampler,
    ) -> Rgb {
        let mut l = Rgb::ZERO;
        for light in self.scene.lights.iter().filter(|&light| to(light)) {
            let u = s.next_2d();
            let Some(ls) = light.sample_li_by_solid_angle(sp.p, u) else {
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
}
