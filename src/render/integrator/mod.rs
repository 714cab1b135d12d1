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
//! caustic). In ppm a gather hit y nearer x than a few global radii, or within one radius of
//! its quad's edges, reads no Indirect photons: its indirect light is one more
//! cosine-sampled ray, whose end is shaded as a gather hit (`gather_near`), because there
//! the map's disc is seen up close or reaches past the surface (`shade.rs`,
//! `NEAR_GATHER_RADII`).

mod direct;
mod seen;
mod shade;
mod smooth;

pub use seen::SeenLights;
pub use shade::{Samples, Scratch, Shader};
pub use smooth::{GatherPixel, smooth_gathers};

use crate::render::photon::{ClassMask, PathClass};
use crate::spec::{EffectSwitches, PhotonStore, RenderSpec};

/// What is estimated at one kind of non-specular path vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VertexPlan {
    /// Direct light by shadow rays (full BSDF).
    pub shadow_rays: bool,
    /// Shadow rays to each area light (a point light takes one; 0 counts as 1): more than
    /// one only where the camera's paths first reach a non-specular surface
    /// (`PhotonMapping::shadow_rays`).
    pub area_shadow_rays: u32,
    /// Caustics from the caustic map.
    pub caustic_map: bool,
    /// Global-map classes read here (through the irradiance cache).
    pub global: ClassMask,
    /// Final gathering over the hemisphere.
    pub gather: bool,
    /// Indirect light by one more cosine-sampled ray, whose end is shaded as a final-gather
    /// hit: at gather hits too near for the global map's disc (`Shader::too_near`).
    pub bounce: bool,
    /// Trace the glossy lobe of Phong materials.
    pub glossy_rays: bool,
}

impl VertexPlan {
    const NOTHING: VertexPlan = VertexPlan {
        shadow_rays: false,
        area_shadow_rays: 1,
        caustic_map: false,
        global: ClassMask::NONE,
        gather: false,
        bounce: false,
        glossy_rays: false,
    };
}

/// What one render reads at the first non-specular vertex of a camera path (`primary`), at a
/// vertex reached by a glossy ray from another (`secondary`), at final-gather hits, and at
/// final-gather hits too near for a fixed-radius global map's disc (`gather_near`, by
/// `Shader::too_near`: the map's indirect light replaced by one more bounce).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    pub primary: VertexPlan,
    pub secondary: VertexPlan,
    pub gather_hit: VertexPlan,
    pub gather_near: VertexPlan,
}

impl Plan {
    pub fn new(spec: &RenderSpec) -> Plan {
        Plan::for_transport(spec).switched(spec.effects)
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
                area_shadow_rays: v.area_shadow_rays,
                caustic_map: v.caustic_map && e.caustics,
                global: ClassMask(global),
                gather: v.gather && e.diffuse_interreflection,
                bounce: v.bounce && e.diffuse_interreflection,
                glossy_rays: v.glossy_rays,
            }
        };
        let (primary, secondary) = (apply(self.primary), apply(self.secondary));
        let gathered = |v: VertexPlan| {
            if primary.gather {
                v
            } else {
                VertexPlan::NOTHING
            }
        };
        Plan {
            primary,
            secondary,
            gather_hit: gathered(self.gather_hit),
            gather_near: gathered(self.gather_near),
        }
    }

    /// The plan of the integrator and photon store, with every effect on: shadow rays only
    /// for an integrator without photons, else as its photon store and gathering say.
    fn for_transport(spec: &RenderSpec) -> Plan {
        use PathClass::*;
        let nothing = VertexPlan::NOTHING;
        let only = |v: VertexPlan| Plan {
            primary: v,
            secondary: v,
            gather_hit: nothing,
            gather_near: nothing,
        };
        match spec.photon_mapping() {
            None => only(VertexPlan {
                shadow_rays: true,
                ..nothing
            }),
            Some(p) if p.photon_store == PhotonStore::DirectOnly => only(VertexPlan {
                global: ClassMask::of(&[Direct]),
                ..nothing
            }),
            Some(p) => {
                let indirect = p.photon_store == PhotonStore::Indirect;
                let direct_from_map = if indirect { vec![] } else { vec![Direct] };
                let read = |extra: &[PathClass]| {
                    let mut c = direct_from_map.clone();
                    c.extend_from_slice(extra);
                    ClassMask::of(&c)
                };
                let secondary = VertexPlan {
                    shadow_rays: indirect,
                    area_shadow_rays: 1,
                    caustic_map: true,
                    global: read(&[Indirect]),
                    gather: false,
                    bounce: false,
                    glossy_rays: true,
                };
                let gather = p.gather_rays > 0;
                let primary = VertexPlan {
                    area_shadow_rays: p.shadow_rays,
                    ..if gather {
                        VertexPlan {
                            global: read(&[]),
                            gather: true,
                            ..secondary
                        }
                    } else {
                        secondary
                    }
                };
                let (gather_hit, gather_near) = if gather {
                    let hit = VertexPlan {
                        shadow_rays: indirect,
                        global: read(&[Caustic, Indirect]),
                        glossy_rays: true,
                        ..nothing
                    };
                    let near = VertexPlan {
                        global: read(&[Caustic]),
                        bounce: true,
                        ..hit
                    };
                    (hit, near)
                } else {
                    (nothing, nothing)
                };
                Plan {
                    primary,
                    secondary,
                    gather_hit,
                    gather_near,
                }
            }
        }
    }

    fn vertices(&self) -> [VertexPlan; 4] {
        [
            self.primary,
            self.secondary,
            self.gather_hit,
            self.gather_near,
        ]
    }

    /// The global-map classes any vertex reads: what the irradiance cache must hold.
    pub fn global_classes(&self) -> ClassMask {
        ClassMask(self.vertices().iter().fold(0, |acc, v| acc | v.global.0))
    }

    pub fn needs_caustic_map(&self) -> bool {
        self.vertices().iter().any(|v| v.caustic_map)
    }
}
