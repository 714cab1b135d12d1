//! One photon path, an interaction at a time (Jensen 2001, chapter 5): emission from a light
//! picked in proportion to power, then at each hit storage (at non-specular surfaces, as the
//! map asks) and scattering by the BSDF with Russian roulette. The tracer (`trace.rs`) keeps
//! four paths in flight and finds their hits together; a path only ever sees its own hits
//! and its own random stream, so what it stores is the same however it is scheduled.

use super::{IRRADIANCE_STRIDE, PathClass, Photon, PhotonStore};
use crate::render::geometry::{PrimHit, Ray, Surface, spawn_ray};
use crate::render::light::{Emission, LightPicker};
use crate::render::material::Transport;
use crate::render::math::{Rgb, max_component};
use crate::render::sampling::{Sampler, Stream, splitmix64};
use crate::render::scene::Scene;

/// Which map a tracing run fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Target {
    Global(PhotonStore),
    /// Only light -> specular+ -> non-specular paths; tracing stops at the first
    /// non-specular hit.
    Caustic,
}

impl Target {
    /// Whether a path stores at most one photon in this map (at its first non-specular
    /// hit): nothing later on the path can be stored, so tracing stops there.
    pub(super) fn one_per_path(self) -> bool {
        matches!(
            self,
            Target::Caustic | Target::Global(PhotonStore::DirectOnly)
        )
    }

    fn keeps(self, class: PathClass) -> bool {
        match self {
            Target::Global(store) => store.keeps(class),
            Target::Caustic => class == PathClass::Caustic,
        }
    }
}

/// What every photon path of one tracing run shares.
pub(super) struct PathSetup<'a> {
    pub(super) scene: &'a Scene,
    pub(super) picker: &'a LightPicker,
    pub(super) target: Target,
    pub(super) max_depth: u32,
    /// Aim the photon at the caustic targets.
    pub(super) aim: bool,
    /// Path i draws from random stream (seed, stream, i) alone.
    pub(super) seed: u64,
    pub(super) stream: Stream,
}

/// A photon in flight: the ray it travels next and what it carries.
pub(super) struct PhotonPath {
    pub(super) ray: Ray,
    /// Flux relative to the map's unit, total / emitted: luminance 1 when it leaves the
    /// light (on average, for aimed caustic photons).
    power: Rgb,
    /// Surface interactions so far.
    depth: u32,
    non_specular_before: bool,
    /// Global-map paths picked to carry irradiance points (see `emit`).
    irradiance_point: bool,
    sampler: Sampler,
    /// The path's place in its tracing chunk: its photons are put back in path order.
    pub(super) slot: u32,
}

impl PhotonPath {
    /// A lane without a path (see `trace.rs`), to be overwritten by [`PhotonPath::emit`].
    pub(super) fn idle() -> PhotonPath {
        PhotonPath {
            ray: Ray::new(glam::Vec3A::ZERO, glam::Vec3A::Z),
            power: Rgb::ZERO,
            depth: 0,
            non_specular_before: false,
            irradiance_point: false,
            sampler: Sampler::idle(),
            slot: 0,
        }
    }

    /// Path `index` leaving its light, written into `into` with `slot`, its place in its
    /// tracing chunk; false (and `into` untouched) if it would end before its first hit: no
    /// interaction allowed, a zero weight, or (blind caustic photons) a direction that
    /// reaches no specular object.
    pub(super) fn emit(setup: &PathSetup, index: u64, slot: u32, into: &mut PhotonPath) -> bool {
        let PathSetup {
            scene,
            picker,
            target,
            max_depth,
            aim,
            seed,
            stream,
        } = *setup;
        if max_depth == 0 {
            return false;
        }
        let mut s = Sampler::new(seed, stream, index);
        // Global-map paths are picked to carry irradiance points by a hash of their index: a
        // thinning independent of where their photons land.
        let irradiance_point = matches!(target, Target::Global(_))
            && splitmix64(index ^ splitmix64(seed)).is_multiple_of(IRRADIANCE_STRIDE);
        let (li, p_light) = picker.pick(s.next_f32());
        let (u_pos, u_dir) = (s.next_2d(), s.next_2d());
        let light = &scene.lights[li];
        let em = if aim {
            // Aimed at the specular objects (photon/targets.rs), weighted by the light's own
            // direction pdf over the aiming pdf.
            let origin = light.emission_origin(u_pos);
            let td = scene
                .caustic_targets
                .sample(origin.sp.p, s.next_f32(), u_dir);
            let weight = origin.direction_pdf(td.dir) / td.pdf;
            if !(weight > 0.0) || !weight.is_finite() {
                return false;
            }
            Emission {
                ray: origin.ray(td.dir),
                flux: light.power() * weight,
            }
        } else {
            let em = light.sample_emission(u_pos, u_dir);
            if target == Target::Caustic && !scene.caustic_targets.may_reach(em.ray.o, em.ray.d) {
                return false; // it would end unstored at its first hit (see `may_reach`)
            }
            em
        };
        *into = PhotonPath {
            ray: em.ray,
            power: em.flux / (p_light * picker.total),
            depth: 0,
            non_specular_before: false,
            irradiance_point,
            sampler: s,
            slot,
        };
        true
    }

    /// The interaction at `hit`, the closest hit of `self.ray`: store a photon into `out`
    /// if the map keeps it, then scatter. Returns whether the path goes on.
    #[inline]
    pub(super) fn interact(
        &mut self,
        setup: &PathSetup,
        hit: Option<PrimHit>,
        out: &mut Vec<Photon>,
    ) -> bool {
        let Some(hit) = hit.map(|h| setup.scene.hit_point(&self.ray, h)) else {
            return false;
        };
        let Surface::Material(mi) = setup.scene.surface(hit.point.prim) else {
            return false; // lights absorb
        };
        let m = &setup.scene.materials[mi as usize];
        let wo = -self.ray.d;
        if !m.is_specular() {
            let class = if self.depth == 0 {
                PathClass::Direct
            } else if self.non_specular_before {
                PathClass::Indirect
            } else {
                PathClass::Caustic
            };
            let n = hit.point.n;
            let n_side = if n.dot(wo) < 0.0 { -n } else { n };
            if setup.target.keeps(class) {
                out.push(Photon::new(
                    hit.point.p,
                    self.power,
                    n_side,
                    class,
                    self.irradiance_point,
                ));
            }
            if setup.target.one_per_path() {
                return false;
            }
        }
        let s = &mut self.sampler;
        let Some(bs) = m.sample(
            wo,
            hit.point.n,
            s.next_f32(),
            s.next_2d(),
            Transport::Importance,
        ) else {
            return false;
        };
        // Russian roulette by the sampled albedo keeps photon power about constant.
        let survive = max_component(bs.weight).min(1.0);
        if !(survive > 0.0) || s.next_f32() >= survive {
            return false;
        }
        self.power *= bs.weight / survive;
        self.non_specular_before |= !bs.specular;
        self.ray = spawn_ray(&hit.point, bs.wi);
        self.depth += 1;
        self.depth < setup.max_depth
    }
}
