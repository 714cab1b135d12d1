//! The camera pass: radiance along a camera ray, following the plan of `integrator/mod.rs`.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3A;

use super::smooth::GatherSample;
use super::{Plan, VertexPlan};
use crate::render::control::Control;
use crate::render::geometry::{Hit, Ray, Surface, SurfacePoint, spawn_ray};
use crate::render::material::{Material, SpecularBranch, Transport};
use crate::render::math::{Frame, Rgb, luminance, reflect};
use crate::render::photon::{ClassMask, Density, DensityScratch};
use crate::render::qmc::Branch;
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
    pub caustic: Option<Density<'a>>,
    pub global: Option<Density<'a>>,
    pub gather_rays: u32,
    pub max_depth: u32,
    /// Read within long final gathers (see [`GATHER_CHECK`]).
    pub control: Control<'a>,
    /// Which points of the pixels' quasi-random sequences this camera pass draws.
    pub samples: Samples,
    /// Leave each camera sample's final gather at the point the camera sees in the scratch
    /// ([`GatherSample`]), for the film to keep (ppm's smoothed gathers, `smooth.rs`).
    pub record_gathers: bool,
    /// Where the camera may see a light directly: there the light surfaces seen first are
    /// read by rays of their own (`seen.rs`).
    pub seen: &'a super::SeenLights,
}

/// Which points of each pixel's Sobol sequence a camera pass draws: sample j is point
/// `first + j` of the pixel's sequence under `seed`. A one-shot render starts at 0; pass i
/// of a progressive one (spp samples a pass) at (i - 1) spp under the job's seed, so that
/// its passes stratify each other as one pass's samples do.
#[derive(Clone, Copy, Debug)]
pub struct Samples {
    pub seed: u64,
    pub first: u64,
}

/// Gather rays that end within this many radii of a fixed-radius global map (ppm's) of
/// their gather point, or within one of their quad's edges, read no indirect light from the
/// map but bounce once more (`plan.gather_near`). Near an edge a density estimate's disc
/// reaches past the surface and counts too few photons; a short gather ray shows any blur
/// of the map undiluted, and rays from across a room land in the bands along its edges.
/// ppm with gathering after 128 passes on cornell: block_err 0.0035 reading the map at
/// every hit, 0.0027 with the near hits bouncing (2, 4 and 8 radii alike), 0.0023 with the
/// quads' edges too (docs/performance-history.md, "near gather hits bounce once more"). The
/// radius shrinks over the passes, and so does the share of gather rays that bounce again.
const NEAR_GATHER_RADII: f32 = 4.0;

/// How many bounces in a row a gather ray's hits too near for the global map may take
/// before one reads it however near: a bound on a gather ray's rays wherever it lands
/// (among quads narrower than the radius, or in a crevice, every hit is near). In
/// tests/ppm.rs's cube corner, with 1, 2, 3 and unbounded: blocks 0.9934-1.0005,
/// 0.9973-1.0014, 0.9980-1.0019 and 0.9982-1.0020 of `pt`'s.
const NEAR_BOUNCES: u32 = 3;

/// Gather rays between two reads of the cancel flag: 65,536 gather rays (the limit) at one
/// point take a good fraction of a second, and cancel must stop a render within one.
const GATHER_CHECK: u32 = 64;

/// Per-thread scratch memory.
#[derive(Default)]
pub struct Scratch {
    density: DensityScratch,
    /// The last camera sample's gather (with [`Shader::record_gathers`]), which the film
    /// takes after every sample (`film.rs`, `add_extra`).
    pub gather: Option<GatherSample>,
}

/// Whether a ray counts the light surfaces it reaches, so that no light path is counted
/// twice (the table in `integrator/mod.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Emission {
    /// Count them: camera paths, and glossy rays where no shadow rays sample the lights.
    Count,
    /// Count them only after a mirror or glass: shadow rays from the glossy surface sampled
    /// the lights it sees directly, but cannot see one through a specular surface.
    AfterSpecular,
    /// Never: gather rays. A light seen from a diffuse point, even through mirrors or glass,
    /// is direct light (shadow rays) or a caustic (the caustic map).
    Never,
}

/// What a ray carries about the path it continues.
#[derive(Clone, Copy)]
struct Segment<'p> {
    depth: u32,
    emission: Emission,
    /// How to shade the first non-specular vertex this ray reaches.
    vertex: &'p VertexPlan,
    /// Split at glass into both branches (only on the camera's own specular chain).
    split: bool,
    /// How many more times in a row a gather ray's hit too near for the global map
    /// ([`Shader::too_near`]) may bounce instead of reading it: [`NEAR_BOUNCES`] for a gather
    /// ray, one less for each bounce, 0 for any other ray.
    near_bounces: u32,
}

impl<'p> Segment<'p> {
    /// The segment after a specular bounce.
    fn through_specular(self) -> Segment<'p> {
        Segment {
            depth: self.depth + 1,
            emission: match self.emission {
                Emission::AfterSpecular => Emission::Count,
                e => e,
            },
            ..self
        }
    }
}

impl Shader<'_> {
    /// Radiance arriving at the camera along `ray`.
    pub fn camera_ray(&self, ray: &Ray, s: &mut Sampler, scratch: &mut Scratch) -> Rgb {
        self.camera_segment(ray, Emission::Count, s, scratch)
    }

    /// Radiance along camera ray `ray`, counting the light surfaces it reaches as `emission`.
    pub(super) fn camera_segment(
        &self,
        ray: &Ray,
        emission: Emission,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let seg = Segment {
            depth: 0,
            emission,
            vertex: &self.plan.primary,
            split: true,
            near_bounces: 0,
        };
        self.trace(ray, seg, s, scratch)
    }

    /// Radiance along `ray`.
    fn trace(&self, ray: &Ray, seg: Segment, s: &mut Sampler, scratch: &mut Scratch) -> Rgb {
        let Some(hit) = self.scene.intersect(ray) else {
            return Rgb::ZERO;
        };
        let wo = -ray.d;
        match self.scene.surface(hit.point.prim) {
            Surface::Light(li) if seg.emission == Emission::Count => {
                self.scene.lights[li as usize].emitted(hit.point.n, wo)
            }
            Surface::Light(_) => Rgb::ZERO,
            Surface::Material(mi) => {
                let m = &self.scene.materials[mi as usize];
                if m.is_specular() {
                    return self.specular(m, &hit, wo, seg, s, scratch);
                }
                let seg = if seg.near_bounces > 0 && self.too_near(&hit) {
                    Segment {
                        vertex: &self.plan.gather_near,
                        ..seg
                    }
                } else {
                    seg
                };
                self.non_specular(m, &hit.point, wo, seg, s, scratch)
            }
        }
    }

    /// Follow mirror and glass: both branches near the camera, one further down.
    fn specular(
        &self,
        m: &Material,
        hit: &Hit,
        wo: Vec3A,
        seg: Segment,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        if seg.depth + 1 >= self.max_depth {
            return Rgb::ZERO;
        }
        let b = m.specular_branches(wo, hit.point.n, Transport::Radiance);
        let next = seg.through_specular();
        let mut follow = |br: SpecularBranch, scale: f32, s: &mut Sampler| {
            let ray = spawn_ray(&hit.point, br.wi);
            br.weight * scale * self.trace(&ray, next, s, scratch)
        };
        match (b.reflection, b.transmission) {
            (Some(r), Some(t)) if seg.split && seg.depth < SPLIT_DEPTH => {
                follow(r, 1.0, s) + follow(t, 1.0, s)
            }
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

    /// Radiance leaving a non-specular point toward `wo`, estimated as `seg.vertex` says.
    fn non_specular(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: Vec3A,
        seg: Segment,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let vertex = seg.vertex;
        let n_side = if sp.n.dot(wo) < 0.0 { -sp.n } else { sp.n };
        let rho = m.diffuse_reflectance();
        let mut l = Rgb::ZERO;
        if vertex.shadow_rays {
            l += self.direct_light(m, sp, wo, vertex.area_shadow_rays, s);
        }
        if rho != Rgb::ZERO {
            if vertex.caustic_map
                && let Some(cm) = &self.caustic
            {
                let e = cm.irradiance(sp.p, n_side, ClassMask::ALL, &mut scratch.density);
                l += rho * FRAC_1_PI * e;
            }
            if !vertex.global.is_empty()
                && let Some(global) = &self.global
            {
                let e = global.irradiance(sp.p, n_side, vertex.global, &mut scratch.density);
                l += rho * FRAC_1_PI * e;
            }
            if vertex.gather {
                let g = self.final_gather(sp, n_side, seg.depth, s, scratch);
                l += rho * g;
                if self.record_gathers && seg.depth == 0 {
                    scratch.gather = Some(GatherSample {
                        p: sp.p,
                        n: n_side,
                        g,
                        rho,
                    });
                }
            }
            if vertex.bounce {
                l += rho * self.bounce(sp, n_side, seg, s, scratch);
            }
        }
        if vertex.glossy_rays {
            l += self.glossy(m, sp, wo, n_side, seg, s, scratch);
        }
        l
    }

    /// The glossy lobe of a Phong surface, by one ray sampled from the lobe alone:
    /// f_s cos / pdf = ks (e + 2) / (e + 1) cos(theta_i). What it reaches is shaded as a
    /// secondary vertex (photon maps read directly: gathering happens once per path).
    #[allow(clippy::too_many_arguments)]
    fn glossy(
        &self,
        m: &Material,
        sp: &SurfacePoint,
        wo: Vec3A,
        n_side: Vec3A,
        seg: Segment,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let Material::Phong {
            specular, exponent, ..
        } = *m
        else {
            return Rgb::ZERO;
        };
        if specular == Rgb::ZERO || seg.depth + 1 >= self.max_depth {
            return Rgb::ZERO;
        }
        let r = reflect(wo, n_side);
        let wi = Frame::from_normal(r).to_world(power_cosine(s.next_2d(), exponent));
        let cos = wi.dot(n_side);
        if cos <= 0.0 {
            return Rgb::ZERO;
        }
        let weight = specular * ((exponent + 2.0) / (exponent + 1.0) * cos);
        let next = Segment {
            depth: seg.depth + 1,
            emission: if seg.vertex.shadow_rays {
                Emission::AfterSpecular
            } else {
                Emission::Count
            },
            vertex: &self.plan.secondary,
            split: false,
            near_bounces: 0,
        };
        weight * self.trace(&spawn_ray(sp, wi), next, s, scratch)
    }

    /// Final gathering (Jensen 2001, section 9.1.4): the mean radiance over cosine-sampled
    /// directions of the hemisphere, read at the first non-specular hit of each gather ray.
    /// Multiplied by rho this is the indirect diffuse radiance at the point. Gather ray i
    /// draws from branch i of the sample's stream, so that with quasi-random samples a
    /// pixel's gather directions over all its samples are one stratified set.
    fn final_gather(
        &self,
        sp: &SurfacePoint,
        n_side: Vec3A,
        depth: u32,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        let frame = Frame::from_normal(n_side);
        let seg = self.gather_segment(depth, NEAR_BOUNCES);
        let mut sum = Rgb::ZERO;
        for i in 0..self.gather_rays {
            // Cut short when cancelled: `render_film` checks the flag after the sample and
            // drops it, so what is returned then is never used.
            if i % GATHER_CHECK == GATHER_CHECK - 1 && self.control.check().is_err() {
                break;
            }
            let mut b = s.branch(Branch::Gather, i, self.gather_rays);
            let wi = frame.to_world(cosine_hemisphere(b.next_2d()));
            sum += self.trace(&spawn_ray(sp, wi), seg, &mut b, scratch);
        }
        sum / self.gather_rays as f32
    }

    /// A gather ray's segment from a vertex at `depth` ([`Segment::near_bounces`]).
    fn gather_segment(&self, depth: u32, near_bounces: u32) -> Segment<'_> {
        Segment {
            depth: depth + 1,
            emission: Emission::Never,
            vertex: &self.plan.gather_hit,
            split: false,
            near_bounces,
        }
    }

    /// Whether a gather ray's hit is too near for a fixed-radius global map's disc there:
    /// nearer its gather point than [`NEAR_GATHER_RADII`] radii, or within one of its quad's
    /// edges. Never for an adaptive (k-NN) map, whose radius varies from hit to hit.
    #[inline]
    fn too_near(&self, hit: &Hit) -> bool {
        let r = match self.global.as_ref().and_then(Density::fixed_radius) {
            Some(r) if r > 0.0 => r,
            _ => return false,
        };
        hit.t < NEAR_GATHER_RADII * r || self.scene.near_boundary(hit.point.prim, hit.point.p, r)
    }

    /// Indirect light at a gather hit too near for the global map: seen up close, its blur
    /// would show (a corner's edges darkened, as Jensen 2001, section 9.1.4, notes of short
    /// gather rays), or its disc reaches past an edge. The mean radiance over the hemisphere
    /// by one cosine-sampled ray, whose end is shaded as a gather hit however near.
    fn bounce(
        &self,
        sp: &SurfacePoint,
        n_side: Vec3A,
        seg: Segment,
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        if seg.depth + 1 >= self.max_depth {
            return Rgb::ZERO;
        }
        let wi = Frame::from_normal(n_side).to_world(cosine_hemisphere(s.next_2d()));
        let next = self.gather_segment(seg.depth, seg.near_bounces.saturating_sub(1));
        self.trace(&spawn_ray(sp, wi), next, s, scratch)
    }
}
