//! The pass loop: start or resume the state, run passes until a stop condition or the
//! caller says enough, and report. Each pass traces its own maps (from `pass_seed` alone),
//! renders with fixed-radius estimates and adds its image to the state's sum.

use std::ops::ControlFlow;
use std::time::Instant;

use super::{MAX_RADIUS_FRACTION, PpmState, initial_radius, next_r2, pass_seed};
use crate::render::accuracy::{ImageError, compare};
use crate::render::camera::Camera;
use crate::render::control::{Control, Phase};
use crate::render::effects::Analysis;
use crate::render::film::{Image, render_film};
use crate::render::integrator::Shader;
use crate::render::outcome::{RenderError, RenderOutput};
use crate::render::photon::{Density, PhotonMap, PhotonMaps, RadiusLookup, build_photon_maps};
use crate::render::scene::Scene;
use crate::render::stats::{PassStats, PpmReport, RenderStats, StatsInput, StopReason, collect};
use crate::spec::{Progressive, RenderSpec, Stop};

/// What a progressive render needs besides the scene and spec.
pub(crate) struct PpmRun<'a> {
    pub reference: Option<&'a Image>,
    /// A state to continue from.
    pub resume: Option<PpmState>,
    /// Identifies the scene and spec (`render::fingerprint`); a state resumes only a
    /// render with the same one.
    pub fingerprint: String,
}

/// One render's fixed inputs, shared by its passes.
struct Passes<'a> {
    scene: &'a Scene,
    spec: &'a RenderSpec,
    ppm: &'a Progressive,
    analysis: &'a Analysis,
    camera: Camera,
    control: &'a Control<'a>,
}

/// A finished pass's maps and radii (global, caustic), kept for the final statistics.
struct LastPass {
    maps: PhotonMaps,
    radii: (f32, f32),
}

/// Render passes until `ppm.stop` says enough (or `on_pass`, called with the state after
/// every pass, breaks).
pub(crate) fn render_ppm(
    scene: &Scene,
    spec: &RenderSpec,
    ppm: &Progressive,
    analysis: &Analysis,
    run: PpmRun,
    control: &Control,
    on_pass: &mut dyn FnMut(&PpmState) -> ControlFlow<()>,
) -> Result<RenderOutput, RenderError> {
    let (width, height) = spec.resolution((scene.camera.width, scene.camera.height));
    let camera = scene.camera.clone().with_resolution(width, height);
    let mut state = start_state(run.resume, run.fingerprint, &camera)?;
    let passes = Passes {
        scene,
        spec,
        ppm,
        analysis,
        camera,
        control,
    };
    let tracker = control.tracker(Phase::Passes, ppm.stop.iterations as u64);
    tracker.advance(state.passes as u64);
    let mut last: Option<LastPass> = None;
    // The error of the image so far against this render's reference (a resumed state's
    // recorded error may be against another one).
    let mut error = match run.reference {
        Some(r) if state.passes > 0 => compare(&state.image(), r).ok(),
        _ => None,
    };
    let stopped_by = loop {
        if let Some(reason) = should_stop(&state, &ppm.stop, error) {
            break reason;
        }
        control.check()?;
        // One pass's maps at a time: the last pass's go before this pass's are traced.
        drop(last.take());
        let done = passes.run_pass(&mut state, run.reference)?;
        error = state.last.as_ref().and_then(|p| p.error);
        last = Some(done);
        tracker.advance(1);
        if on_pass(&state).is_break() {
            break StopReason::Paused;
        }
    };
    let stats = passes.report(&state, last.as_ref(), stopped_by, error);
    Ok(RenderOutput {
        image: state.image(),
        stats,
    })
}

/// A fresh state, or the one to resume if it is this render's.
fn start_state(
    resume: Option<PpmState>,
    fingerprint: String,
    camera: &Camera,
) -> Result<PpmState, RenderError> {
    match resume {
        Some(s)
            if s.fingerprint != fingerprint
                || (s.width, s.height) != (camera.width, camera.height) =>
        {
            Err(RenderError::Input(
                "the saved state belongs to another scene, resolution or parameters".into(),
            ))
        }
        Some(s) => Ok(s),
        None => Ok(PpmState::new(fingerprint, camera.width, camera.height)),
    }
}

impl Passes<'_> {
    /// Trace the pass's maps, render it with the state's radii, add it to the state and
    /// shrink the radii.
    fn run_pass(
        &self,
        state: &mut PpmState,
        reference: Option<&Image>,
    ) -> Result<LastPass, RenderError> {
        let (spec, pass_spec) = (self.spec, &self.ppm.pass);
        let pass = state.passes + 1;
        let seed = pass_seed(spec.seed, pass);
        let t0 = Instant::now();
        let photon_params = crate::render::photon::PhotonParams {
            seed,
            ..self.analysis.photon_params.clone()
        };
        let maps = build_photon_maps(self.scene, &photon_params, self.control)?;
        if pass == 1 {
            self.set_initial_radii(state, &maps);
        }
        let radii = (
            state.r2_global.sqrt() as f32,
            state.r2_caustic.sqrt() as f32,
        );
        fn lookup(m: &Option<PhotonMap>, r: f32) -> Option<Density<'_>> {
            m.as_ref().map(|m| Density::Radius(RadiusLookup::new(m, r)))
        }
        let shader = Shader {
            scene: self.scene,
            plan: self.analysis.plan,
            caustic: lookup(&maps.caustic, radii.1),
            global: lookup(&maps.global, radii.0),
            gather_rays: pass_spec.gather_rays,
            max_depth: spec.max_depth,
            control: *self.control,
        };
        let t_render = Instant::now();
        let film = render_film(&shader, &self.camera, pass_spec.spp, seed, self.control)?;
        let render = t_render.elapsed().as_secs_f64();
        drop(shader);
        state.add_pass(&film.image);
        state.passes = pass;
        state.nonfinite_samples += film.nonfinite_samples;
        let alpha = self.ppm.alpha;
        state.r2_global = next_r2(state.r2_global, pass, alpha);
        state.r2_caustic = next_r2(state.r2_caustic, pass, alpha);
        // The pass's time, not counting the comparison with the reference below.
        let elapsed = state.elapsed() + t0.elapsed().as_secs_f64();
        let error = reference.and_then(|r| compare(&state.image(), r).ok());
        let stored = |m: &Option<PhotonMap>| m.as_ref().map_or(0, |m| m.len() as u64);
        let radius = |m: &Option<PhotonMap>, r: f32| if m.is_some() { r as f64 } else { 0.0 };
        state.record(PassStats {
            pass,
            radius_global: radius(&maps.global, radii.0),
            radius_caustic: radius(&maps.caustic, radii.1),
            photon_trace: maps.trace_seconds,
            build_maps: maps.build_seconds,
            render,
            elapsed,
            global_stored: stored(&maps.global),
            caustic_stored: stored(&maps.caustic),
            error,
        });
        Ok(LastPass { maps, radii })
    }

    /// The initial radii, given or from the first pass's photons.
    fn set_initial_radii(&self, state: &mut PpmState, maps: &PhotonMaps) {
        let r_max = MAX_RADIUS_FRACTION * self.scene.extent().max(f32::MIN_POSITIVE);
        let k = self.ppm.pass.k;
        let r0 = |m: &Option<PhotonMap>| match (self.ppm.radius, m) {
            (Some(r), _) => r as f64,
            (None, Some(m)) => initial_radius(m, k, r_max) as f64,
            (None, None) => 0.0,
        };
        state.radius_initial = [r0(&maps.global), r0(&maps.caustic)];
        state.r2_global = state.radius_initial[0].powi(2);
        state.r2_caustic = state.radius_initial[1].powi(2);
    }

    /// STATS.json of the render: the last pass's maps, times summed over the passes, and
    /// the `ppm` section.
    fn report(
        &self,
        state: &PpmState,
        last: Option<&LastPass>,
        stopped_by: StopReason,
        error: Option<ImageError>,
    ) -> RenderStats {
        // Stats of the last pass's maps (none if a resumed render had no pass left to run).
        let no_maps;
        let (maps, (rg, rc)) = match last {
            Some(l) => (&l.maps, l.radii),
            None => {
                no_maps = PhotonMaps::none(self.analysis.photon_params.clone());
                (&no_maps, (0.0, 0.0))
            }
        };
        let mut stats = collect(&StatsInput {
            scene: self.scene,
            maps,
            spec: self.spec,
            camera: &self.camera,
            cache: None,
            radii: (rc, rg),
            times: (0.0, 0.0),
            nonfinite_samples: state.nonfinite_samples,
            effects: self.analysis.effects.clone(),
        });
        sum_times(&mut stats.times, state);
        stats.error = error;
        stats.ppm = Some(PpmReport {
            alpha: self.ppm.alpha,
            passes: state.passes,
            radius_initial_global: state.radius_initial[0],
            radius_initial_caustic: state.radius_initial[1],
            radius_source: if self.ppm.radius.is_some() {
                "radius"
            } else {
                "auto"
            },
            stopped_by,
            history: state.history.clone(),
        });
        stats
    }
}

/// Whether to stop before another pass.
fn should_stop(state: &PpmState, stop: &Stop, error: Option<ImageError>) -> Option<StopReason> {
    if state.passes >= stop.iterations {
        return Some(StopReason::Iterations);
    }
    if state.passes == 0 {
        return None;
    }
    if let (Some(target), Some(e)) = (stop.target_error, error)
        && e.relmse <= target
    {
        return Some(StopReason::TargetError);
    }
    if let Some(limit) = stop.time_limit {
        let elapsed = state.elapsed();
        let mean_pass = elapsed / state.passes as f64;
        if elapsed + mean_pass > limit {
            return Some(StopReason::TimeLimit);
        }
    }
    None
}

/// Totals over the passes into the render's `times`.
fn sum_times(t: &mut crate::render::stats::Times, state: &PpmState) {
    t.photon_trace = state.totals.photon_trace;
    t.build_maps = state.totals.build_maps;
    t.precompute = 0.0;
    t.render = state.totals.render;
    t.total = state.elapsed();
}
