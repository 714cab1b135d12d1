//! The job's effect switches in the bidirectional family, and what STATS.json says of them.
//!
//! An effect is what the camera sees at the first non-specular vertex x of a path (counted
//! from the camera): direct light (the light's next vertex is x), a caustic (only specular
//! vertices between the light and x) or diffuse interreflection (a non-specular vertex
//! between them), as for photon mapping (`render/integrator`). Every technique knows enough
//! of the path it makes to tell which: the camera subpath's first non-specular vertex, and
//! whether a light vertex had a non-specular vertex before it. A light seen directly or
//! through specular surfaces only is no effect at a point: it always counts.

use std::collections::BTreeMap;

use super::Modes;
use crate::render::stats::Effect;
use crate::spec::EffectSwitches;

/// What a path shows at its first non-specular vertex from the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Shows {
    /// A light, directly or through specular surfaces only.
    Light,
    Direct,
    Caustic,
    Indirect,
}

impl Shows {
    /// The class of a path whose vertex x is seen by the camera (first non-specular), given
    /// how many light subpath vertices lead to x (`light_len`, 0: x sees the light itself)
    /// and whether one of them is non-specular.
    pub fn at_light_side(light_len: u32, non_specular_before: bool) -> Shows {
        match (light_len, non_specular_before) {
            (0, _) => Shows::Direct,
            (_, false) => Shows::Caustic,
            (_, true) => Shows::Indirect,
        }
    }

    pub fn shown(self, e: EffectSwitches) -> bool {
        match self {
            Shows::Light => true,
            Shows::Direct => e.direct_light,
            Shows::Caustic => e.caustics,
            Shows::Indirect => e.diffuse_interreflection,
        }
    }
}

/// STATS.json's effects for the family: how each is carried, or that the job switched it
/// off, replacing the photon-mapping descriptions of the shared analysis.
pub(super) fn describe(effects: &mut BTreeMap<String, Effect>, modes: Modes, e: EffectSwitches) {
    let (direct, caustics, indirect) = match modes {
        Modes::Pt => (
            "next-event estimation and BSDF sampling, MIS (balance heuristic)",
            "BSDF sampling reaching area lights (a point light's caustics cannot be reached)",
            "path tracing with next-event estimation",
        ),
        Modes::Lt => (
            "light tracing (light vertices connected to the camera)",
            "light tracing",
            "light tracing",
        ),
        Modes::Bdpt => (
            "every vertex connection, MIS",
            "light tracing and vertex connections, MIS",
            "every vertex connection, MIS",
        ),
        Modes::Vcm => (
            "vertex connection and merging, MIS",
            "vertex merging, light tracing and connections, MIS",
            "vertex connection and merging, MIS",
        ),
    };
    for (name, on, how) in [
        ("direct_light", e.direct_light, direct),
        ("caustics", e.caustics, caustics),
        (
            "diffuse_interreflection",
            e.diffuse_interreflection,
            indirect,
        ),
    ] {
        let entry = if on {
            Effect {
                simulated: true,
                how: how.to_string(),
                reason: "every light path the scene allows is sampled".to_string(),
            }
        } else {
            Effect {
                simulated: false,
                how: "none".to_string(),
                reason: format!("switched off by the job (effects.{name}: false)"),
            }
        };
        effects.insert(name.to_string(), entry);
    }
    if modes == Modes::Lt {
        camera_sees_no_specular(effects);
    }
}

/// Light tracing joins light vertices to the camera directly, never through a delta BSDF:
/// light paths reflect and refract as in every technique, but what the camera would see in
/// a mirror or through glass stays black, and STATS.json says so.
fn camera_sees_no_specular(effects: &mut BTreeMap<String, Effect>) {
    let seen = [
        ("specular_reflection", "reflected in a mirror or glass"),
        ("refraction", "through glass"),
    ];
    for (name, what) in seen {
        if let Some(e) = effects.get_mut(name)
            && e.simulated
        {
            e.how = "on light paths only".to_string();
            e.reason = format!(
                "light tracing joins light vertices to the camera directly: what the camera \
                 would see {what} stays black (pt, bdpt and vcm render it)"
            );
        }
    }
}
