//! The pass loop every progressive integrator shares (ppm, and the bidirectional family):
//! start or resume the state, run passes until a stop condition or the caller says enough,
//! add each pass's image to the state's f64 sum, shrink the radii by Knaus and Zwicker's
//! schedule, and report. Pass i draws its random numbers from `pass_seed(seed, i)` alone,
//! so a render stopped and resumed gives the same bytes as one that never stopped.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::render::accuracy::{ImageError, compare};
use crate::render::control::{Control, Phase};
use crate::render::film::Image;
use crate::render::outcome::{RenderError, RenderOutput};
use crate::render::ppm::{PpmState, next_r2, pass_seed};
use crate::render::stats::{AutoChoice, PassStats, PpmReport, RenderStats, StopReason, Times};
use crate::spec::Stop;

/// What one pass made.
pub(crate) struct PassOutput {
    pub image: Image,
    pub nonfinite_samples: u64,
    /// The radii the pass's estimates read with (global, caustic; 0 where none).
    pub radii: (f64, f64),
    pub photon_trace: f64,
    pub build_maps: f64,
    pub render: f64,
    /// Photons (or light vertices) the pass stored, in its global and caustic maps.
    pub stored: (u64, u64),
}

/// Which pass, and its random seed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PassAt {
    pub pass: u32,
    pub seed: u64,
}

pub(crate) type PassResult = Result<PassOutput, RenderError>;

/// A progressive integrator: its passes and what it reports.
pub(crate) trait Progression {
    /// Render pass `at.pass` (1-based) from random seed `at.seed`, reading its estimates
    /// with the state's squared radii. Pass 1 sets the state's initial radii (and squared
    /// radii) first, when the integrator has any.
    fn pass(&mut self, state: &mut PpmState, at: PassAt, control: &Control) -> PassResult;

    /// Set the state's initial radii (and squared radii) as pass 1 (`at`) would, without
    /// rendering it: a piece of passes that starts later needs them (see [`Piece`]).
    fn initial_radii(
        &mut self,
        state: &mut PpmState,
        at: PassAt,
        control: &Control,
    ) -> Result<(), RenderError>;

    /// The render's statistics but for its times, error and progressive section.
    fn stats(&self, state: &PpmState) -> RenderStats;
}

/// What a progressive render needs besides its integrator.
pub(crate) struct ProgressiveRun<'a> {
    pub reference: Option<&'a Image>,
    /// A state to continue from.
    pub resume: Option<PpmState>,
    /// Identifies the scene and spec (`render::fingerprint`); a state resumes only a
    /// render with the same one.
    pub fingerprint: String,
    pub stop: &'a Stop,
    /// The render's seed: pass i draws from `pass_seed(seed, i)`.
    pub seed: u64,
    /// The radius schedule's alpha (integrators that merge), and whether the initial radius
    /// was given.
    pub radius: Option<(f64, bool)>,
    pub size: (u32, u32),
    /// Render only these passes (a farm's task), from a state positioned before them.
    pub piece: Option<Piece>,
    /// What `auto` chose (made now, or the one a resumed state kept), kept in the state:
    /// its seconds count against a time limit ([`PpmState::choosing`]).
    pub choice: Option<AutoChoice>,
}

/// Passes `first .. first + count` (1-based) of a progressive render, rendered on their
/// own: the state starts as the whole render's would be after pass `first - 1` (its pass
/// count and radii; pass 1's initial radii computed as pass 1 computes them) but with a
/// zero sum, so the sum at the end holds these passes only and merges exactly with the
/// other pieces' ([`crate::render::ppm::PassSum::merge`]). Radii are replayed by the same
/// f64 schedule, so each pass reads with the bits it would read with in one run.
///
/// `radii`: the render's initial radii (global, caustic), when the caller knows them from
/// an earlier piece of the same render (`PpmState::radius_initial`): a piece past pass 1
/// then does not compute them again (for ppm, a photon trace of pass 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    pub first: u32,
    pub count: u32,
    pub radii: Option<[f64; 2]>,
}

impl Piece {
    /// The piece's last pass.
    pub fn last(&self) -> u32 {
        self.first + self.count - 1
    }
}

/// Render passes until `run.stop` says enough (or `on_pass`, called with the state after
/// every pass, breaks).
pub(crate) fn run_passes(
    integrator: &mut dyn Progression,
    run: ProgressiveRun,
    control: &Control,
    on_pass: &mut dyn FnMut(&PpmState) -> ControlFlow<()>,
) -> Result<RenderOutput, RenderError> {
    let piece_stop;
    let (mut state, stop) = match run.piece {
        None => (
            start_state(run.resume, &run.fingerprint, run.size)?,
            run.stop,
        ),
        Some(piece) => {
            piece_stop = check_piece(piece, &run)?;
            let state = piece_state(integrator, piece, &run, control)?;
            (state, &piece_stop)
        }
    };
    if run.choice.is_some() {
        state.choice = run.choice;
    }
    let tracker = control.tracker(Phase::Passes, stop.pass_limit() as u64);
    tracker.advance(state.passes as u64);
    // The error of the image so far against this render's reference (a resumed state's
    // recorded error may be against another one).
    let mut error = match run.reference {
        Some(r) if state.passes > 0 => compare(&state.image(), r).ok(),
        _ => None,
    };
    let stopped_by = loop {
        if let Some(reason) = should_stop(&state, stop, error) {
            break reason;
        }
        control.check()?;
        let pass = state.passes + 1;
        let t0 = Instant::now();
        let at = PassAt {
            pass,
            seed: pass_seed(run.seed, pass),
        };
        let out = integrator.pass(&mut state, at, control)?;
        add_pass(&mut state, pass, &out, run.radius.map(|r| r.0));
        // The pass's time, not counting the comparison with the reference below.
        let elapsed = state.elapsed() + t0.elapsed().as_secs_f64();
        error = run.reference.and_then(|r| compare(&state.image(), r).ok());
        state.record(PassStats {
            pass,
            radius_global: out.radii.0,
            radius_caustic: out.radii.1,
            photon_trace: out.photon_trace,
            build_maps: out.build_maps,
            render: out.render,
            elapsed,
            global_stored: out.stored.0,
            caustic_stored: out.stored.1,
            error,
        });
        tracker.advance(1);
        if on_pass(&state).is_break() {
            break StopReason::Paused;
        }
    };
    Ok(report(integrator, &state, run.radius, stopped_by, error))
}

/// The render's output once its passes stopped: the mean image and the stats, with the
/// times summed over the passes and the progressive section.
fn report(
    integrator: &dyn Progression,
    state: &PpmState,
    radius: Option<(f64, bool)>,
    stopped_by: StopReason,
    error: Option<ImageError>,
) -> RenderOutput {
    let mut stats = integrator.stats(state);
    sum_times(&mut stats.times, state);
    stats.error = error;
    stats.ppm = Some(PpmReport {
        alpha: radius.map_or(0.0, |r| r.0),
        passes: state.passes,
        radius_initial_global: state.radius_initial[0],
        radius_initial_caustic: state.radius_initial[1],
        radius_source: match radius {
            Some((_, true)) => "radius",
            Some((_, false)) => "auto",
            None => "none",
        },
        stopped_by,
        history: state.history.clone(),
    });
    RenderOutput {
        image: state.image(),
        stats,
    }
}

/// Add a pass to the state: its image to the sum, and the next pass's radii.
fn add_pass(state: &mut PpmState, pass: u32, out: &PassOutput, alpha: Option<f64>) {
    state.add_pass(&out.image);
    state.passes = pass;
    state.nonfinite_samples += out.nonfinite_samples;
    if let Some(alpha) = alpha {
        state.r2_global = next_r2(state.r2_global, pass, alpha);
        state.r2_caustic = next_r2(state.r2_caustic, pass, alpha);
    }
}

/// A piece must lie within a render that stops by its pass count alone (a time limit or a
/// target error cannot be split ahead of time), and not continue a saved state. Its stop:
/// its last pass.
fn check_piece(piece: Piece, run: &ProgressiveRun) -> Result<Stop, RenderError> {
    let input = |m: &str| Err(RenderError::Input(m.to_string()));
    if piece.first == 0 || piece.count == 0 || piece.first.checked_add(piece.count).is_none() {
        return input("a piece of passes starts at pass 1 or later and has at least one");
    }
    if piece.last() > run.stop.pass_limit() {
        return input("a piece of passes ends after the render's last pass");
    }
    if run.stop.time_limit.is_some() || run.stop.target_error.is_some() {
        return input("only a render that stops by its pass count splits into pieces");
    }
    if run.resume.is_some() {
        return input("a piece of passes does not continue a saved state");
    }
    Ok(Stop::after(piece.last()))
}

/// The state before `piece`'s first pass, its sum zero.
fn piece_state(
    integrator: &mut dyn Progression,
    piece: Piece,
    run: &ProgressiveRun,
    control: &Control,
) -> Result<PpmState, RenderError> {
    let mut state = PpmState::new(run.fingerprint.clone(), run.size.0, run.size.1);
    if piece.first == 1 {
        return Ok(state);
    }
    let first = PassAt {
        pass: 1,
        seed: pass_seed(run.seed, 1),
    };
    match piece.radii {
        // As the integrators set them: the squared radii are the radii squared.
        Some(r) => {
            state.radius_initial = r;
            state.r2_global = r[0].powi(2);
            state.r2_caustic = r[1].powi(2);
        }
        None => integrator.initial_radii(&mut state, first, control)?,
    }
    if let Some((alpha, _)) = run.radius {
        for pass in 1..piece.first {
            state.r2_global = next_r2(state.r2_global, pass, alpha);
            state.r2_caustic = next_r2(state.r2_caustic, pass, alpha);
        }
    }
    state.passes = piece.first - 1;
    Ok(state)
}

/// A fresh state, or the one to resume if it is this render's.
fn start_state(
    resume: Option<PpmState>,
    fingerprint: &str,
    (width, height): (u32, u32),
) -> Result<PpmState, RenderError> {
    match resume {
        Some(s) if s.fingerprint != fingerprint || (s.width, s.height) != (width, height) => {
            Err(RenderError::Input(
                "the saved state belongs to another scene, resolution or parameters".into(),
            ))
        }
        Some(s) => Ok(s),
        None => Ok(PpmState::new(fingerprint.to_string(), width, height)),
    }
}

/// Whether to stop before another pass. `auto`'s pilot counts against the time limit
/// (`--time-limit T` is the whole render's T), not in the mean pass by which the next one is
/// foreseen.
fn should_stop(state: &PpmState, stop: &Stop, error: Option<ImageError>) -> Option<StopReason> {
    if state.passes >= stop.pass_limit() {
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
        if state.choosing() + elapsed + mean_pass > limit {
            return Some(StopReason::TimeLimit);
        }
    }
    None
}

/// Totals over the passes into the render's `times`.
fn sum_times(t: &mut Times, state: &PpmState) {
    t.photon_trace = state.totals.photon_trace;
    t.build_maps = state.totals.build_maps;
    t.precompute = 0.0;
    t.render = state.totals.render;
    t.total = state.elapsed();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state after `passes` passes of 0.1 s each, and `auto`'s pilot of `pilot` seconds.
    fn after(passes: u32, pilot: f64) -> PpmState {
        let mut state = PpmState::new(String::new(), 1, 1);
        state.choice = Some(AutoChoice {
            params: serde_json::Value::Null,
            effect: crate::render::stats::Effect {
                simulated: true,
                how: "auto chose ppm".into(),
                reason: String::new(),
            },
            seconds: pilot,
        });
        state.passes = passes;
        state.last = Some(PassStats {
            pass: passes,
            radius_global: 0.0,
            radius_caustic: 0.0,
            photon_trace: 0.0,
            build_maps: 0.0,
            render: 0.1,
            elapsed: 0.1 * passes as f64,
            global_stored: 0,
            caustic_stored: 0,
            error: None,
        });
        state
    }

    /// `--time-limit 1` with a pilot of 0.45 s: passes stop where the pilot and they would
    /// pass 1 s with another, not at 1 s of passes alone; the pilot is not taken for a pass.
    #[test]
    fn a_time_limit_counts_the_seconds_spent_choosing() {
        let stop = Stop {
            iterations: None,
            time_limit: Some(1.0),
            target_error: None,
        };
        let stops = |passes, pilot| should_stop(&after(passes, pilot), &stop, None).is_some();
        assert!(!stops(4, 0.45), "0.45 + 0.4 + 0.1 is within 1 s");
        assert!(stops(5, 0.45), "0.45 + 0.5 + 0.1 is past 1 s");
        assert!(!stops(8, 0.0), "without a pilot, 0.8 + 0.1 is within 1 s");
        assert!(stops(10, 0.0), "1.0 + 0.1 is past 1 s");
        // At least one pass, whatever the pilot took.
        assert!(!stops(0, 5.0));
    }
}
