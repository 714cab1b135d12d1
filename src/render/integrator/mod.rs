//! Integrators: which light paths each one estimates, and how.
//!
//! Jensen's split of the rendering equation at the first non-specular point x a camera path
//! reaches (Jensen 2001, section 9.1) is L(x) = direct + caustics + indirect diffuse (+ glossy
//! and specular reflection, ray traced). Every light path L (S|D)* D(x) falls in exactly one
//! term, by the path class of the photons that carry it:
//!
//! | mode (`--photon-store`, gather G) | direct at x   | caustics at x | indirect at x                                        |
//! |-----------------------------------|---------------|---------------|------------------------------------------------------|
//! | raytrace                          | shadow rays   | -             | -                                                    |
//! | photon indirect, G = 0            | shadow rays   | caustic map   | global map, class Indirect                           |
//! | photon indirect, G > 0            | shadow rays   | caustic map   | gather; at y: shadow rays + global Caustic, Indirect |
//! | photon all, G = 0                 | global Direct | caustic map   | global map, class Indirect                           |
//! | photon all, G > 0                 | global Direct | caustic map   | gather; at y: global map, all classes                |
//! | photon direct_only                | global Direct | -             | -                                                    |
//!
//! Maps are read through the Lambertian part of a BSDF (rho/pi); a Phong surface's glossy
//! lobe is ray traced instead, at x and at gather hits y, by one ray whose end is shaded like
//! the G = 0 rows (final gathering happens once per camera path). Emission reached by a ray
//! counts only where nothing else accounts for it: always on camera paths; for glossy rays
//! only through a mirror or glass when shadow rays sampled the light directly; never for
//! gather rays (a light seen from x, even through specular surfaces, is direct light or a
//! caustic).

mod shade;

pub use shade::{Scratch, Shader};

use crate::render::photon::{ClassMask, PathClass, PhotonStore};

/// The closed set of integrators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IntegratorKind {
    /// Direct light by shadow rays and perfect specular chains; no photon maps.
    Raytrace,
    /// Jensen-style photon mapping with global and caustic maps.
    Photon,
    /// Progressive photon mapping (Knaus and Zwicker 2011): independent passes of `photon`
    /// with fixed-radius estimates whose radius shrinks, averaged (see `render::ppm`).
    Ppm,
}

impl IntegratorKind {
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Raytrace => "raytrace",
            IntegratorKind::Photon => "photon",
            IntegratorKind::Ppm => "ppm",
        }
    }
}

/// Everything a render job can set besides the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderParams {
    pub integrator: IntegratorKind,
    /// Photons emitted for the global map.
    pub photons: u64,
    /// Photons emitted for the caustic map.
    pub caustic_photons: u64,
    /// Photons per radiance estimate.
    pub k: usize,
    pub photon_store: PhotonStore,
    /// Final-gather rays per camera sample at the first diffuse point; 0 reads the global map.
    pub gather_rays: u32,
    /// Jittered samples per pixel (box filter).
    pub spp: u32,
    /// Longest path (surface interactions) for photons and camera rays.
    pub max_depth: u32,
    pub seed: u64,
    /// Resolution override (else the scene's camera).
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// `ppm`: passes to render (a stop condition; see `render::ppm::Stop` for the others).
    pub iterations: u32,
    /// `ppm`: radius reduction, r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1), in (0, 1).
    pub alpha: f64,
    /// `ppm`: initial radius of both maps' estimates (scene units); `None`: from the k-NN
    /// radius of the first pass's photons (see `render::ppm::initial_radius`).
    pub radius: Option<f32>,
    /// Aim caustic photons at the specular objects (`photon/targets.rs`); false emits them
    /// in every direction, as the seed did (its timing tables are measured that way).
    pub aim_caustics: bool,
    /// Effects the job switched off (to see their contribution, or to save time).
    pub effects: EffectSwitches,
}

/// Effects a job may switch off, each for what the camera sees: at the first non-specular
/// point of a camera path and at points seen through a glossy reflection. Light that
/// reaches those points by other paths (direct light at a final-gather hit is indirect
/// light at the point gathering) stays with the effect it belongs to there.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EffectSwitches {
    pub direct_light: bool,
    /// Caustics from the caustic map; off, no caustic photon is traced.
    pub caustics: bool,
    /// Light from other diffuse surfaces (global map, final gathering).
    pub diffuse_interreflection: bool,
}

impl EffectSwitches {
    pub const ALL_ON: EffectSwitches = EffectSwitches {
        direct_light: true,
        caustics: true,
        diffuse_interreflection: true,
    };
}

impl Default for EffectSwitches {
    fn default() -> Self {
        EffectSwitches::ALL_ON
    }
}

/// Default passes of `ppm`.
pub const DEFAULT_ITERATIONS: u32 = 16;

/// Most passes of `ppm` (a pass costs at least a photon trace and a camera pass).
pub const MAX_ITERATIONS: u32 = 1_000_000;

/// A render parameter out of range: the field (snake_case, as the server's JSON names it;
/// the CLI flag is `--` and the name with dashes) and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct ParamError {
    pub field: &'static str,
    pub message: String,
}

/// Largest photon count per map (about 30 GB of photons at worst).
pub const MAX_PHOTONS: u64 = 1_000_000_000;

impl RenderParams {
    /// Check every parameter's range; the engine assumes valid parameters.
    pub fn validate(&self) -> Result<(), ParamError> {
        use crate::render::camera::MAX_IMAGE_SIDE;
        let bad = |field, message: String| Err(ParamError { field, message });
        for (field, v) in [("width", self.width), ("height", self.height)] {
            if let Some(v) = v
                && !(1..=MAX_IMAGE_SIDE).contains(&v)
            {
                return bad(field, format!("must be in 1..={MAX_IMAGE_SIDE}, got {v}"));
            }
        }
        for (field, v) in [
            ("photons", self.photons),
            ("caustic_photons", self.caustic_photons),
        ] {
            if v > MAX_PHOTONS {
                return bad(field, format!("must be at most {MAX_PHOTONS}, got {v}"));
            }
        }
        if !(1..=100_000).contains(&self.k) {
            return bad("k", format!("must be in 1..=100000, got {}", self.k));
        }
        if !(1..=65_536).contains(&self.spp) {
            return bad("spp", format!("must be in 1..=65536, got {}", self.spp));
        }
        if !(1..=1024).contains(&self.max_depth) {
            return bad(
                "max_depth",
                format!("must be in 1..=1024, got {}", self.max_depth),
            );
        }
        if self.gather_rays > 65_536 {
            return bad(
                "gather_rays",
                format!("must be at most 65536, got {}", self.gather_rays),
            );
        }
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return bad(
                "iterations",
                format!("must be in 1..={MAX_ITERATIONS}, got {}", self.iterations),
            );
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return bad(
                "alpha",
                format!("must be in (0, 1) (exclusive), got {}", self.alpha),
            );
        }
        if let Some(r) = self.radius
            && !(r > 0.0 && r.is_finite())
        {
            return bad("radius", format!("must be a positive number, got {r}"));
        }
        if self.integrator != IntegratorKind::Ppm {
            let d = RenderParams::default();
            if self.iterations != d.iterations {
                return bad("iterations", "only for integrator ppm".into());
            }
            if self.alpha != d.alpha {
                return bad("alpha", "only for integrator ppm".into());
            }
            if self.radius.is_some() {
                return bad("radius", "only for integrator ppm".into());
            }
        }
        Ok(())
    }

    /// The parameters with `ppm`'s defaults where they differ from `photon`'s: one sample
    /// per pixel and no final gathering per pass (the passes average both out).
    pub fn ppm_defaults() -> RenderParams {
        RenderParams {
            integrator: IntegratorKind::Ppm,
            spp: 1,
            gather_rays: 0,
            iterations: DEFAULT_ITERATIONS,
            // Only sets the initial radius: a small k starts with little blur, and the
            // passes average its noise away (k = 10 against 50: block_err 0.014 against
            // 0.020 after 64 passes on the caustic scene; docs/accuracy.md).
            k: 10,
            photons: 100_000,
            caustic_photons: 100_000,
            ..RenderParams::default()
        }
    }
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            integrator: IntegratorKind::Photon,
            photons: 200_000,
            caustic_photons: 200_000,
            k: 50,
            photon_store: PhotonStore::Indirect,
            gather_rays: 8,
            spp: 4,
            max_depth: 32,
            seed: 1,
            width: None,
            height: None,
            iterations: 1,
            alpha: 0.7,
            radius: None,
            aim_caustics: true,
            effects: EffectSwitches::ALL_ON,
        }
    }
}

/// What is estimated at one kind of non-specular path vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VertexPlan {
    /// Direct light by shadow rays (full BSDF).
    pub shadow_rays: bool,
    /// Caustics from the caustic map.
    pub caustic_map: bool,
    /// Global-map classes read here (through the irradiance cache).
    pub global: ClassMask,
    /// Final gathering over the hemisphere.
    pub gather: bool,
    /// Trace the glossy lobe of Phong materials.
    pub glossy_rays: bool,
}

impl VertexPlan {
    const NOTHING: VertexPlan = VertexPlan {
        shadow_rays: false,
        caustic_map: false,
        global: ClassMask::NONE,
        gather: false,
        glossy_rays: false,
    };
}

/// What one render reads at the first non-specular vertex of a camera path (`primary`), at a
/// vertex reached by a glossy ray from another (`secondary`), and at final-gather hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    pub primary: VertexPlan,
    pub secondary: VertexPlan,
    pub gather_hit: VertexPlan,
}

impl Plan {
    pub fn new(p: &RenderParams) -> Plan {
        Plan::for_transport(p).switched(p.effects)
    }

    /// Drop what the job switched off from the vertices the camera sees (primary and
    /// secondary); final-gather hits are left whole, as they make up indirect light.
    fn switched(self, e: EffectSwitches) -> Plan {
        let apply = |v: VertexPlan| {
            let mut global = v.global.0;
            if !e.direct_light {
                global &= !ClassMask::of(&[PathClass::Direct]).0;
            }
            if !e.diffuse_interreflection {
                global &= !ClassMask::of(&[PathClass::Indirect]).0;
            }
            VertexPlan {
                shadow_rays: v.shadow_rays && e.direct_light,
                caustic_map: v.caustic_map && e.caustics,
                global: ClassMask(global),
                gather: v.gather && e.diffuse_interreflection,
                glossy_rays: v.glossy_rays,
            }
        };
        let (primary, secondary) = (apply(self.primary), apply(self.secondary));
        Plan {
            primary,
            secondary,
            gather_hit: if primary.gather {
                self.gather_hit
            } else {
                VertexPlan::NOTHING
            },
        }
    }

    /// The plan of the integrator and photon store, with every effect on.
    fn for_transport(p: &RenderParams) -> Plan {
        use PathClass::*;
        let nothing = VertexPlan::NOTHING;
        match (p.integrator, p.photon_store) {
            (IntegratorKind::Raytrace, _) => {
                let v = VertexPlan {
                    shadow_rays: true,
                    ..nothing
                };
                Plan {
                    primary: v,
                    secondary: v,
                    gather_hit: nothing,
                }
            }
            (IntegratorKind::Photon | IntegratorKind::Ppm, PhotonStore::DirectOnly) => {
                let v = VertexPlan {
                    global: ClassMask::of(&[Direct]),
                    ..nothing
                };
                Plan {
                    primary: v,
                    secondary: v,
                    gather_hit: nothing,
                }
            }
            (IntegratorKind::Photon | IntegratorKind::Ppm, store) => {
                let indirect = store == PhotonStore::Indirect;
                let direct_from_map = if indirect { vec![] } else { vec![Direct] };
                let read = |extra: &[PathClass]| {
                    let mut c = direct_from_map.clone();
                    c.extend_from_slice(extra);
                    ClassMask::of(&c)
                };
                let secondary = VertexPlan {
                    shadow_rays: indirect,
                    caustic_map: true,
                    global: read(&[Indirect]),
                    gather: false,
                    glossy_rays: true,
                };
                let gather = p.gather_rays > 0;
                let primary = if gather {
                    VertexPlan {
                        global: read(&[]),
                        gather: true,
                        ..secondary
                    }
                } else {
                    secondary
                };
                let gather_hit = if gather {
                    VertexPlan {
                        shadow_rays: indirect,
                        global: read(&[Caustic, Indirect]),
                        glossy_rays: true,
                        ..nothing
                    }
                } else {
                    nothing
                };
                Plan {
                    primary,
                    secondary,
                    gather_hit,
                }
            }
        }
    }

    fn vertices(&self) -> [VertexPlan; 3] {
        [self.primary, self.secondary, self.gather_hit]
    }

    /// The global-map classes any vertex reads: what the irradiance cache must hold.
    pub fn global_classes(&self) -> ClassMask {
        ClassMask(self.vertices().iter().fold(0, |acc, v| acc | v.global.0))
    }

    pub fn needs_caustic_map(&self) -> bool {
        self.vertices().iter().any(|v| v.caustic_map)
    }
}
