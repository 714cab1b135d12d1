//! Progressive photon mapping (Knaus and Zwicker 2011, "Progressive Photon Mapping: A
//! Probabilistic Approach", ACM TOG 30(3)).
//!
//! Each pass is an independent `photon` render: fresh photon maps (random numbers from the
//! seed and the pass index alone), read by fixed-radius estimates, direct light by shadow
//! rays. The image is the mean of the passes. Between passes the squared radius shrinks as
//!
//!   r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1),
//!
//! (their eq. 19 with a global radius), so that the variance of the mean and its expected
//! error both go to zero: the render converges, where a single `photon` render keeps its
//! blur whatever its photon count. Only one pass's maps exist at a time, so memory does not
//! grow with the number of passes; the running state ([`PpmState`]) is the sum image, the
//! pass index and the radii, and resuming from it gives the same bytes as never stopping.

mod state;

pub use state::{PassStats, PassTotals, PpmState, StateError, kept_in_history};

use std::ops::ControlFlow;
use std::time::Instant;

use serde::Serialize;

use crate::render::accuracy::{ImageError, compare};
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::effects::analyse;
use crate::render::film::{Image, render_film};
use crate::render::integrator::{RenderParams, Shader};
use crate::render::photon::{
    Density, KnnScratch, PhotonMap, PhotonMaps, RadiusLookup, build_photon_maps,
};
use crate::render::pipeline::{RenderOutput, StatsInput, collect_stats};
use crate::render::sampling::splitmix64;
use crate::render::scene::Scene;

/// The automatic initial radius is the median k-NN distance at this many photons of the
/// first pass's map (spread evenly over the map).
const RADIUS_SAMPLES: usize = 1024;

/// Initial radii never exceed this fraction of the scene's extent.
const MAX_RADIUS_FRACTION: f32 = 0.1;

/// When a progressive render stops (the first condition met wins; at least one pass runs).
#[derive(Clone, Debug, PartialEq)]
pub struct Stop {
    /// Passes in all (counting those of a resumed state).
    pub iterations: u32,
    /// Seconds of passes in all: no pass starts that would, at the mean pass time so far,
    /// end after this.
    pub time_limit: Option<f64>,
    /// Stop once `relmse` against the reference is at most this.
    pub target_error: Option<f64>,
}

impl Stop {
    /// Stop after `iterations` passes, and on nothing else.
    pub fn after(iterations: u32) -> Stop {
        Stop {
            iterations,
            time_limit: None,
            target_error: None,
        }
    }
}

/// Why a progressive render stopped.
#[derive(Serialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    Iterations,
    TimeLimit,
    TargetError,
    /// The caller's per-pass callback asked to stop (to yield, or to save and exit).
    Paused,
}

/// The `ppm` section of STATS.json.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct PpmReport {
    pub alpha: f64,
    pub passes: u32,
    /// Initial radius of the global and caustic maps' estimates (scene units).
    pub radius_initial_global: f64,
    pub radius_initial_caustic: f64,
    /// "radius": given; "auto": median k-NN distance (k = `params.k`) in the first pass.
    pub radius_source: &'static str,
    pub stopped_by: StopReason,
    /// Every pass up to 256, then thinned to about 256 per doubling of the pass count.
    pub history: Vec<PassStats>,
}

/// Why a progressive render could not run.
#[derive(Debug, thiserror::Error)]
pub enum PpmError {
    #[error(transparent)]
    Cancelled(#[from] Cancelled),
    /// A state or reference that does not belong to this render.
    #[error("{0}")]
    Input(String),
}

/// What a progressive render needs besides the scene and parameters.
pub struct PpmOptions<'a> {
    pub stop: Stop,
    pub reference: Option<&'a Image>,
    /// A state to continue from.
    pub resume: Option<PpmState>,
    /// Identifies scene and parameters (see [`fingerprint`]).
    pub fingerprint: String,
}

impl<'a> PpmOptions<'a> {
    /// A fresh render (no state to resume, no reference) that stops as `stop` says.
    pub fn new(stop: Stop, fingerprint: String) -> PpmOptions<'a> {
        PpmOptions {
            stop,
            reference: None,
            resume: None,
            fingerprint,
        }
    }
}

pub struct PpmOutput {
    pub output: RenderOutput,
    pub state: PpmState,
}

/// A stable identity of a scene (its source text) and the parameters that shape the
/// image (all but the number of passes).
pub fn fingerprint(scene_source: &[u8], params: &RenderParams) -> String {
    let p = RenderParams {
        iterations: 0,
        ..params.clone()
    };
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in scene_source.iter().chain(format!("{p:?}").as_bytes()) {
        h = (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// The random seed of pass `pass` (1-based).
pub fn pass_seed(seed: u64, pass: u32) -> u64 {
    splitmix64(seed ^ splitmix64(0x7070_6d00_0000_0000 | pass as u64))
}

/// r_{i+1}^2 from r_i^2 after pass i (1-based).
#[inline]
pub fn next_r2(r2: f64, i: u32, alpha: f64) -> f64 {
    r2 * (i as f64 + alpha) / (i as f64 + 1.0)
}

/// The median distance to the k-th nearest other photon (on a surface facing the same way),
/// over photons spread evenly through the map, capped at `r_max`.
pub fn initial_radius(map: &PhotonMap, k: usize, r_max: f32) -> f32 {
    let items = map.tree.items();
    if items.is_empty() {
        return r_max;
    }
    let step = items.len().div_ceil(RADIUS_SAMPLES);
    let mut scratch = KnnScratch::default();
    let mut r: Vec<f32> = items
        .iter()
        .step_by(step)
        .map(|ph| {
            let n = ph.normal();
            let filter = |q: &crate::render::photon::Photon| q.normal().dot(n) > 0.8;
            let r2 = map
                .tree
                .knn(ph.pos.into(), k + 1, r_max * r_max, &filter, &mut scratch);
            r2.sqrt()
        })
        .collect();
    r.sort_by(f32::total_cmp);
    r[r.len() / 2].min(r_max)
}

/// Render passes until `opts.stop` says enough (or `on_pass`, called with the state after
/// every pass, breaks).
pub fn render_ppm(
    scene: &Scene,
    params: &RenderParams,
    opts: PpmOptions,
    control: &Control,
    on_pass: &mut dyn FnMut(&PpmState) -> ControlFlow<()>,
) -> Result<PpmOutput, PpmError> {
    let analysis = analyse(scene, params);
    let camera = scene.camera.clone().with_resolution(
        params.width.unwrap_or(scene.camera.width),
        params.height.unwrap_or(scene.camera.height),
    );
    let mut state = match opts.resume {
        Some(s) => {
            if s.fingerprint != opts.fingerprint
                || (s.width, s.height) != (camera.width, camera.height)
            {
                return Err(PpmError::Input(
                    "the saved state belongs to another scene, resolution or parameters".into(),
                ));
            }
            s
        }
        None => PpmState::new(opts.fingerprint.clone(), camera.width, camera.height),
    };
    if let Some(r) = opts.reference
        && (r.width, r.height) != (camera.width, camera.height)
    {
        return Err(PpmError::Input(format!(
            "the reference is {}x{}, the image {}x{}: render at the reference's size",
            r.width, r.height, camera.width, camera.height
        )));
    }
    let r_max = MAX_RADIUS_FRACTION * scene.extent().max(f32::MIN_POSITIVE);
    let alpha = params.alpha;
    let tracker = control.tracker(Phase::Passes, opts.stop.iterations as u64);
    tracker.advance(state.passes as u64);
    let mut last_maps = None;
    // The error of the image so far against this render's reference (a resumed state's
    // recorded error may be against another one).
    let mut last_error = match opts.reference {
        Some(r) if state.passes > 0 => compare(&state.image(), r).ok(),
        _ => None,
    };
    let stopped_by = loop {
        if let Some(reason) = should_stop(&state, &opts.stop, last_error) {
            break reason;
        }
        control.check()?;
        let pass = state.passes + 1;
        let seed = pass_seed(params.seed, pass);
        let t0 = Instant::now();
        let photon_params = crate::render::photon::PhotonParams {
            seed,
            ..analysis.photon_params.clone()
        };
        // One pass's maps at a time: the last pass's go before this pass's are traced.
        drop(last_maps.take());
        let maps = build_photon_maps(scene, &photon_params, control)?;
        if pass == 1 {
            let r0 = |m: &Option<PhotonMap>| match (params.radius, m) {
                (Some(r), _) => r as f64,
                (None, Some(m)) => initial_radius(m, params.k, r_max) as f64,
                (None, None) => 0.0,
            };
            state.radius_initial = [r0(&maps.global), r0(&maps.caustic)];
            state.r2_global = state.radius_initial[0].powi(2);
            state.r2_caustic = state.radius_initial[1].powi(2);
        }
        let (rg, rc) = (
            state.r2_global.sqrt() as f32,
            state.r2_caustic.sqrt() as f32,
        );
        let shader = Shader {
            scene,
            plan: analysis.plan,
            caustic: maps
                .caustic
                .as_ref()
                .map(|m| Density::Radius(RadiusLookup::new(m, rc))),
            global: maps
                .global
                .as_ref()
                .map(|m| Density::Radius(RadiusLookup::new(m, rg))),
            gather_rays: params.gather_rays,
            max_depth: params.max_depth,
            control: *control,
        };
        let t_render = Instant::now();
        let film = render_film(&shader, &camera, params.spp, seed, control)?;
        let render = t_render.elapsed().as_secs_f64();
        drop(shader);
        state.add_pass(&film.image);
        state.passes = pass;
        state.nonfinite_samples += film.nonfinite_samples;
        state.r2_global = next_r2(state.r2_global, pass, alpha);
        state.r2_caustic = next_r2(state.r2_caustic, pass, alpha);
        // The pass's time, not counting the comparison with the reference below.
        let elapsed = state.elapsed() + t0.elapsed().as_secs_f64();
        last_error = opts.reference.and_then(|r| compare(&state.image(), r).ok());
        let stored = |m: &Option<PhotonMap>| m.as_ref().map_or(0, |m| m.len() as u64);
        state.record(PassStats {
            pass,
            radius_global: if maps.global.is_some() {
                rg as f64
            } else {
                0.0
            },
            radius_caustic: if maps.caustic.is_some() {
                rc as f64
            } else {
                0.0
            },
            photon_trace: maps.trace_seconds,
            build_maps: maps.build_seconds,
            render,
            elapsed,
            global_stored: stored(&maps.global),
            caustic_stored: stored(&maps.caustic),
            error: last_error,
        });
        last_maps = Some((maps, rg, rc));
        tracker.advance(1);
        if on_pass(&state).is_break() {
            break StopReason::Paused;
        }
    };
    let image = state.image();
    // Stats of the last pass's maps (none if a resumed render had no pass left to run).
    let no_maps;
    let (maps, (rg, rc)) = match &last_maps {
        Some((maps, rg, rc)) => (maps, (*rg, *rc)),
        None => {
            no_maps = PhotonMaps::none(analysis.photon_params.clone());
            (&no_maps, (0.0, 0.0))
        }
    };
    let mut stats = collect_stats(&StatsInput {
        scene,
        maps,
        params,
        camera: &camera,
        cache: None,
        radii: (rc, rg),
        times: (0.0, 0.0),
        nonfinite_samples: state.nonfinite_samples,
        effects: analysis.effects,
    });
    sum_times(&mut stats.times, &state);
    stats.error = last_error;
    stats.ppm = Some(PpmReport {
        alpha,
        passes: state.passes,
        radius_initial_global: state.radius_initial[0],
        radius_initial_caustic: state.radius_initial[1],
        radius_source: if params.radius.is_some() {
            "radius"
        } else {
            "auto"
        },
        stopped_by,
        history: state.history.clone(),
    });
    Ok(PpmOutput {
        output: RenderOutput { image, stats },
        state,
    })
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
