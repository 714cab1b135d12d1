//! `auto`: the integrator a scene calls for, from what it holds (the effects analysis's
//! facts), decided before the render starts and reported in STATS.json's
//! `effects.integrator`. The rules follow the race against Mitsuba 3 (docs/performance.md):
//!
//! - mirror or glass lit by a point light: its caustics (light, specular, diffuse) can be
//!   reached only from the light side, and seen through glass only by merging: `vcm`;
//! - mirror or glass and only area lights: every technique reaches every path, merging
//!   still carries caustics seen through glass best: `vcm`;
//! - no mirror or glass: no caustic to merge, and connections between subpaths add little
//!   to next-event estimation: `pt`, the cheapest sample.

use crate::render::light::Light;
use crate::render::math::max_component;
use crate::render::scene::Scene;
use crate::render::stats::Effect;
use crate::spec::{Integrator, Merging, Passes};

/// The integrator for `scene`, with `passes`, and why.
pub(super) fn choose(scene: &Scene, passes: &Passes) -> (Integrator, Effect) {
    let specular = scene.materials.iter().any(|m| m.is_specular());
    let lit_point_light = scene.lights.iter().enumerate().any(|(i, l)| {
        matches!(l, Light::Point { .. })
            && max_component(l.power()) > 0.0
            && scene.shut_in[i].is_none()
    });
    let vcm = || {
        Integrator::Vcm(Merging {
            passes: passes.clone(),
            ..Merging::DEFAULT
        })
    };
    let (integrator, reason) = match (specular, lit_point_light) {
        (true, true) => (
            vcm(),
            "a point light and mirror or glass: its caustics are reached from the light \
             side only, and seen through glass by merging",
        ),
        (true, false) => (
            vcm(),
            "mirror or glass: merging carries the caustics seen through them",
        ),
        (false, _) => (
            Integrator::Pt(passes.clone()),
            "no mirror or glass: no caustic to merge; path tracing with next-event \
             estimation is the cheapest sample",
        ),
    };
    let how = format!("auto chose {}", integrator.name().as_str());
    let effect = Effect {
        simulated: true,
        how,
        reason: reason.to_string(),
    };
    (integrator, effect)
}
