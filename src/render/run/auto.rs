//! `auto`: the integrator a scene calls for, from what it holds (the effects analysis's
//! facts), decided before the render starts and reported in STATS.json's
//! `effects.integrator`. The rules follow the race against Mitsuba 3 (docs/performance.md):
//!
//! - mirror or glass lit by a point light: its caustics (light, specular, diffuse) can be
//!   reached only from the light side, and seen through glass only by merging: `vcm`;
//! - mirror or glass and only area lights: every technique reaches every path, merging
//!   still carries caustics seen through glass best: `vcm`;
//! - no mirror or glass: no caustic to merge; connections between subpaths carry the
//!   indirect light better than path tracing's next-event estimation alone: `bdpt`, the
//!   fastest of ours to Mitsuba's block_err on every diffuse scene of the race (cornell,
//!   knot, cornell_spheres: 0.65-2.8 of Mitsuba's time against pt's 1.8-4.3).

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
            Integrator::Bdpt(passes.clone()),
            "no mirror or glass: no caustic to merge; connections between light and camera \
             subpaths carry the indirect light",
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
