//! `auto`: the integrator a scene and a budget call for, from what the scene holds (the
//! effects analysis's facts) and the spec's stop, decided before the render starts and
//! reported in STATS.json's `effects.integrator`. The rules follow the race against
//! Mitsuba 3 (docs/performance.md, section 6):
//!
//! - mirror or glass, and a time limit alone (no pass count, no target error) that is
//!   short: one `photon` render sized to half the budget. Final gathering over a caustic
//!   map reaches a path tracer's error at that budget in a fraction of it, sooner than any
//!   progressive integrator of ours (which spend their first seconds on noise);
//! - mirror or glass otherwise: caustics (light, specular, diffuse), which from a point
//!   light only the light side reaches, and which seen through glass only merging carries:
//!   `vcm`, which converges;
//! - no mirror or glass: no caustic to merge. `ppm` with final gathering (its rays shaped
//!   by [`GatherShape`], which the pilot picks; half the photons a pass under a short time
//!   limit alone, [`gathering`]): one bounce of a camera path, then the
//!   global map, its gathers stratified over the passes, reached Mitsuba's relmse 1.5-5x
//!   sooner than `pt` on cornell, knot and cornell_spheres (docs/performance.md,
//!   "2026-12-04, late night").
//!   Pilot renders (`pilot.rs`: `pt` and `bdpt`, then where `pt` does poorly gathering and
//!   `bdpt`) find the rooms where gather rays meet the light's bright patch too rarely (a
//!   skewed quad light facing a wall at a few centimetres, which shadow rays sample by
//!   area: relmse 2.3 against `bdpt`'s 0.0041 at 128x128, 6 s;
//!   docs/performance-history.md, "auto's gathering pilot"), and take `bdpt` there.
//!
//! The choice is a function of the scene and the spec alone (never of the machine or the
//! clock), so the same job renders the same bytes from the CLI and the server.

use super::Chosen;
use super::pilot::run_pilot;
use crate::render::control::Control;
use crate::render::outcome::RenderError;
use crate::render::ppm::SMOOTHING_FADE;
use crate::render::scene::Scene;
use crate::render::stats::{AutoChoice, Effect};
use crate::spec::{Integrator, Merging, Passes, PhotonMapping, Progressive, RenderSpec, SpecForm};

/// Photon-mapping settings from small to large, (emitted photons per map, final-gather
/// rays, samples per pixel): the race's ladder, along which the error against the
/// reference falls steadily (block_err 0.049 to 0.0072 on the twin of scene (1)).
const RUNGS: [(u64, u32, u32); 7] = [
    (25_000, 0, 1),
    (100_000, 0, 1),
    (200_000, 4, 2),
    (200_000, 8, 4),
    (400_000, 16, 4),
    (1_000_000, 16, 16),
    (2_000_000, 32, 16),
];

/// Seconds per emitted photon (both maps: tracing and the irradiance precomputation) and
/// per gather ray or camera sample, measured on the race's host (2 cores) on the twins at
/// 256x256 and rounded up (1.0 and 0.45-0.55 microseconds): an upper estimate there, and
/// faster machines only finish sooner.
const SECONDS_PER_PHOTON: f64 = 1.0e-6;
const SECONDS_PER_GATHER_RAY: f64 = 0.6e-6;

/// The predicted seconds of a photon render with `rung` at `pixels`.
fn predicted_seconds((photons, gather, spp): (u64, u32, u32), pixels: u64) -> f64 {
    photons as f64 * SECONDS_PER_PHOTON
        + (pixels * spp as u64 * (gather as u64 + 1)) as f64 * SECONDS_PER_GATHER_RAY
}

/// The photon render for a budget of `seconds` at `pixels`: the largest rung predicted to
/// take at most half of it (the model ignores the scene's size), or none when the budget
/// holds the largest rung twice over: there `vcm`'s converging passes do better (race: at
/// 64 s, vcm's block_err 0.0060 against the largest rung's 0.0072).
fn photon_for_budget(seconds: f64, pixels: u64) -> Option<PhotonMapping> {
    let largest = RUNGS[RUNGS.len() - 1];
    if seconds >= 2.0 * predicted_seconds(largest, pixels) {
        return None;
    }
    let (photons, gather_rays, spp) = RUNGS
        .iter()
        .rev()
        .copied()
        .find(|&r| predicted_seconds(r, pixels) <= seconds / 2.0)
        .unwrap_or(RUNGS[0]);
    Some(PhotonMapping {
        photons,
        caustic_photons: photons,
        gather_rays,
        spp,
        ..PhotonMapping::PHOTON
    })
}

/// The photon render `auto` chooses on a scene with mirror or glass for `passes` at
/// `pixels`, if it chooses one: only for a time limit alone (a pass count or a target error
/// asks for converging passes).
pub(super) fn budget_photon(passes: &Passes, pixels: u64) -> Option<PhotonMapping> {
    photon_for_budget(passes.stop.time_limit_alone()?, pixels)
}

/// The one photon render `auto` chooses for `scene` with `passes` at `pixels`, if it does:
/// mirror or glass and a short time limit alone. No pilot decides it.
fn one_photon_render(scene: &Scene, passes: &Passes, pixels: u64) -> Option<PhotonMapping> {
    let specular = scene.materials.iter().any(|m| m.is_specular());
    budget_photon(passes, pixels).filter(|_| specular)
}

/// `spec` with `auto` resolved where the scene and the spec decide it alone (one photon
/// render), else `spec` itself: what a job's progress is counted by, since the one photon
/// render reports its phases and no passes (the pilot's choices all report passes).
pub fn known_choice(scene: &Scene, spec: &RenderSpec) -> RenderSpec {
    let Integrator::Auto(passes) = &spec.integrator else {
        return spec.clone();
    };
    let (width, height) = spec.resolution((scene.camera.width, scene.camera.height));
    match one_photon_render(scene, passes, width as u64 * height as u64) {
        Some(photon) => RenderSpec {
            integrator: Integrator::Photon(photon),
            ..spec.clone()
        },
        None => spec.clone(),
    }
}

/// The integrator for `scene` at `pixels`, with `passes` (of `spec`, whose seed, depth and
/// switches a pilot renders with), and why.
pub(super) fn choose(
    scene: &Scene,
    spec: &RenderSpec,
    passes: &Passes,
    pixels: u64,
    control: &Control,
) -> Result<(Integrator, Effect), RenderError> {
    let specular = scene.materials.iter().any(|m| m.is_specular());
    let (integrator, reason) = match one_photon_render(scene, passes, pixels) {
        Some(photon) => {
            let reason = format!(
                "mirror or glass and a short time limit: one photon-mapping render sized to \
                 half of it ({} photons a map, {} gather rays, {} spp) reaches a path \
                 tracer's error at that budget sooner than converging passes",
                photon.photons, photon.gather_rays, photon.spp
            );
            (Integrator::Photon(photon), reason)
        }
        _ if specular => {
            let vcm = Merging {
                passes: passes.clone(),
                ..Merging::DEFAULT
            };
            (
                Integrator::Vcm(vcm),
                "mirror or glass: their caustics are reached from a point light's side only, \
                 and seen through glass by merging"
                    .to_string(),
            )
        }
        _ => bdpt_or_gathering(scene, spec, passes, control)?,
    };
    let how = format!("auto chose {}", integrator.name().as_str());
    let effect = Effect {
        simulated: true,
        how,
        reason,
    };
    Ok((integrator, effect))
}

/// A kept choice (a resumed state's, or a farm worker's from an earlier piece), for `spec`
/// as it renders now: the chosen integrator's parameters, with `spec`'s stop conditions.
/// None where the kept form does not parse or is not a progressive integrator's: the pilot
/// then runs again, and, being a function of the scene and the spec, chooses the same.
pub(super) fn recorded(
    kept: &AutoChoice,
    spec: &RenderSpec,
    has_reference: bool,
) -> Option<Chosen> {
    let mut form: SpecForm = serde_json::from_value(kept.params.clone()).ok()?;
    let now = SpecForm::of(spec);
    (form.iterations, form.time_limit, form.target_error) =
        (now.iterations, now.time_limit, now.target_error);
    let chosen = form.to_spec(has_reference).ok()?;
    let progressive = chosen.is_progressive() && !matches!(chosen.integrator, Integrator::Auto(_));
    progressive.then(|| Chosen {
        spec: RenderSpec {
            integrator: chosen.integrator,
            ..spec.clone()
        },
        effect: kept.effect.clone(),
        seconds: kept.seconds,
    })
}

/// How `auto`'s `ppm` spends a pass's final-gather rays. With one camera sample a pixel a
/// pass, the pixels' edges (silhouettes, a box's corners) are most of the error at short
/// budgets where a camera path's bounce finds the light; where it finds the light poorly
/// (a point light's hot spot), the indirect light's noise is, and more rays a sample pay.
/// Measured in docs/performance-history.md, "auto's gathering: 4 rays at 2 samples".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GatherShape {
    /// 4 rays a sample at 2 samples a pixel: where the bounce finds the light.
    OverSamples,
    /// 8 rays a sample at one sample a pixel: where it finds the light poorly.
    OnOneSample,
}

/// How far `auto`'s gathering shares a pass's gathers between pixels, in global-map radii
/// (`render/integrator/smooth.rs`); of 3, 5 and 8 on cornell, 3 helped least at the first
/// pass and 8 blurred most by the 16th (docs/performance-history.md, "smoothed final
/// gathers"). Chosen when the radius faded as pass^-0.5; with the slower fade
/// (`ppm::SMOOTHING_FADE`) 3.5 raised block_err after 1, 4 and 16 passes by 2-6% on knot and
/// cornell, 7 moved it 1-3% either way ("smoothing on planes, fading slower").
const GATHER_SMOOTHING: f32 = 5.0;

/// Shadow rays to each area light per camera sample in `auto`'s gathering: with gathers
/// shared between pixels, what is left of a pixel's noise under an area light is mostly its
/// direct light (soft shadows, the light's extent). Knot after 4 passes (seed 7 against 8):
/// relmse 0.00260, 0.00082 and 0.00060 with 1, 2 and 4, for passes 9% and 16% dearer. 4
/// gains little more after the first passes while its cost grows as the radius shrinks: in
/// the race 2 reached Mitsuba's error sooner than both runs of 4 in 11 of knot's and
/// cornell's 16 cells, later in 3 (relmse at 16 and 64 s, met either way)
/// (docs/performance-history.md, "more shadow rays where the camera looks").
const SHADOW_RAYS: u32 = 2;

/// The longest time limit (given alone) under which `auto`'s gathering traces half of
/// `ppm`'s photons a pass ([`gathering`]).
const SHORT_LIMIT: f64 = 4.0;

/// Whether `passes` stop at a short time limit alone ([`SHORT_LIMIT`]): a budget where what
/// comes first (the pilot, the first passes' photons) is a large share.
pub(super) fn short_limit(passes: &Passes) -> bool {
    (passes.stop.time_limit_alone()).is_some_and(|t| t <= SHORT_LIMIT)
}

/// `ppm` with final gathering as `auto` renders a room whose light a camera path's bounce
/// or a gather ray finds, with `passes`, its gather rays shaped by `shape`.
///
/// Under a short time limit alone ([`SHORT_LIMIT`]) a pass traces half the photons, with
/// half the k, so that the first pass's radius (the median k-NN distance) stays the same:
/// tracing them is a large share of a short render's passes, and the time goes into more
/// passes. Over longer budgets each pass's noisier map costs more than that gains
/// (measured: docs/performance-history.md, "gathering's photons under a short time
/// limit").
pub(super) fn gathering(passes: &Passes, shape: GatherShape) -> Progressive {
    // (gather rays a camera sample, camera samples a pixel for each one the spec asks for)
    let (gather_rays, samples) = match shape {
        GatherShape::OverSamples => (4, 2),
        GatherShape::OnOneSample => (8, 1),
    };
    let full = PhotonMapping::PPM_PASS;
    let share = if short_limit(passes) { 2 } else { 1 };
    Progressive {
        pass: PhotonMapping {
            gather_rays,
            spp: passes.spp.saturating_mul(samples),
            photons: full.photons / share,
            caustic_photons: full.caustic_photons / share,
            k: full.k / share as usize,
            shadow_rays: SHADOW_RAYS,
            ..full
        },
        gather_smoothing: GATHER_SMOOTHING,
        stop: passes.stop.clone(),
        ..Progressive::DEFAULT
    }
}

/// A room without mirror or glass: `bdpt` or `ppm` with final gathering, by the pilot's
/// small renders (`pilot.rs`: `pt` against `bdpt`, then where `pt` does poorly gathering
/// against `bdpt`).
fn bdpt_or_gathering(
    scene: &Scene,
    spec: &RenderSpec,
    passes: &Passes,
    control: &Control,
) -> Result<(Integrator, String), RenderError> {
    let pilot = run_pilot(scene, spec, passes, control)?;
    let gathered = pilot
        .gathering
        .map_or(String::new(), |g| format!(", gathering {g:.3e}"));
    let variances = format!(
        "a pilot's variance per pass: pt {:.3e} (over {} passes), bdpt {:.3e}{gathered} (over \
         {} passes)",
        pilot.pt, pilot.passes[0], pilot.bdpt, pilot.passes[1]
    );
    Ok(if pilot.prefers_bdpt() {
        let why = format!(
            "no mirror or glass: no caustic to merge; {variances}: connections between light \
             and camera subpaths carry this scene's light sooner than final gathering's rays"
        );
        (Integrator::Bdpt(passes.clone()), why)
    } else {
        let ppm = gathering(passes, pilot.gather_shape());
        let why = format!(
            "no mirror or glass: no caustic to merge; {variances}: gather rays find this \
             scene's indirect light, so progressive photon mapping with final gathering \
             ({} rays a camera sample, {} spp a pass, stratified over the passes, shared \
             between neighbouring pixels on one surface within {} global radii over \
             pass^{}) reads the rest from the global map ({} photons a pass); direct light \
             where the camera looks by {} shadow rays a sample to each area light",
            ppm.pass.gather_rays,
            ppm.pass.spp,
            ppm.gather_smoothing,
            SMOOTHING_FADE,
            ppm.pass.photons,
            ppm.pass.shadow_rays
        );
        (Integrator::Ppm(ppm), why)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PIXELS: u64 = 256 * 256;

    /// Longer budgets get larger rungs, up to where vcm takes over; every rung chosen is
    /// predicted to fit half the budget.
    #[test]
    fn the_rung_grows_with_the_budget_until_vcm_takes_over() {
        let photons = |t| photon_for_budget(t, PIXELS).map(|p| p.photons);
        assert_eq!(photons(0.01), Some(25_000));
        assert_eq!(photons(1.0), Some(100_000));
        assert_eq!(photons(4.0), Some(200_000));
        assert_eq!(photons(16.0), Some(400_000));
        assert_eq!(photons(30.0), Some(1_000_000));
        assert_eq!(photons(64.0), None);
        for t in [0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0] {
            if let Some(p) = photon_for_budget(t, PIXELS)
                && p.photons > RUNGS[0].0
            {
                let r = (p.photons, p.gather_rays, p.spp);
                assert!(predicted_seconds(r, PIXELS) <= t / 2.0, "{t} s: {r:?}");
            }
        }
        // Four times the pixels: the same budget buys a smaller rung.
        let big = photon_for_budget(16.0, 4 * PIXELS).expect("a photon render");
        assert!(big.gather_rays * big.spp < 16 * 4);
    }

    /// Gathering traces half the photons a pass, with half the k, under a time limit alone
    /// of at most `SHORT_LIMIT`; with a longer limit, a pass count or a target error, all.
    #[test]
    fn gathering_halves_its_photons_under_a_short_time_limit_alone() {
        let with = |time_limit: Option<f64>, iterations: Option<u32>, target: Option<f64>| {
            let passes = Passes {
                spp: 1,
                stop: crate::spec::Stop {
                    iterations,
                    time_limit,
                    target_error: target,
                },
            };
            let p = gathering(&passes, GatherShape::OverSamples).pass;
            (p.photons, p.caustic_photons, p.k)
        };
        let full = PhotonMapping::PPM_PASS;
        let all = (full.photons, full.caustic_photons, full.k);
        let half = (full.photons / 2, full.caustic_photons / 2, full.k / 2);
        assert_eq!(with(Some(1.0), None, None), half);
        assert_eq!(with(Some(SHORT_LIMIT), None, None), half);
        assert_eq!(with(Some(SHORT_LIMIT * 1.01), None, None), all);
        assert_eq!(with(Some(1.0), Some(8), None), all);
        assert_eq!(with(Some(1.0), None, Some(0.01)), all);
        assert_eq!(with(None, Some(8), None), all);
    }
}
