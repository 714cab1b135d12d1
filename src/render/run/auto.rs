//! `auto`: the integrator a scene calls for, from what it holds (the effects analysis's
//! facts), decided before the render starts and reported in STATS.json's
//! `effects.integrator`. The rules follow the race against Mitsuba 3 (docs/performance.md):
//!
//! - mirror or glass: caustics (light, specular, diffuse), which from a point light only
//!   the light side reaches, and which seen through glass only merging carries: `vcm`;
//! - no mirror or glass: no caustic to merge; connections between subpaths carry the
//!   indirect light better than path tracing's next-event estimation alone: `bdpt`, the
//!   fastest of ours to Mitsuba's block_err on every diffuse scene of the race (cornell,
//!   knot, cornell_spheres: 0.65-2.8 of Mitsuba's time against pt's 1.8-4.3).

use crate::render::scene::Scene;
use crate::render::stats::Effect;
use crate::spec::{Integrator, Merging, Passes};

/// The integrator for `scene`, with `passes`, and why.
pub(super) fn choose(scene: &Scene, passes: &Passes) -> (Integrator, Effect) {
    let (integrator, reason) = if scene.materials.iter().any(|m| m.is_specular()) {
        let vcm = Merging {
            passes: passes.clone(),
            ..Merging::DEFAULT
        };
        (
            Integrator::Vcm(vcm),
            "mirror or glass: their caustics are reached from a point light's side only, \
             and seen through glass by merging",
        )
    } else {
        (
            Integrator::Bdpt(passes.clone()),
            "no mirror or glass: no caustic to merge; connections between light and camera \
             subpaths carry the indirect light",
        )
    };
    let how = format!("auto chose {}", integrator.name().as_str());
    let effect = Effect {
        simulated: true,
        how,
        reason: reason.to_string(),
    };
    (integrator, effect)
}
