//! Running one job on its own rayon pool: resolve the scene, get the photon maps from the
//! cache or trace them, render, write the images, and record the outcome. Progress goes to
//! the job's watch channel; a panic inside the render fails that job only.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde_json::{Value, json};

use super::App;
use super::cache::CacheOutcome;
use super::jobs::{JobParams, ParamsJson, cache_key, resolve_scene};
use super::results::result_path;
use super::state::Snapshot;
use super::store::{Status, now};
use crate::render::effects::analyse;
use crate::render::film::Image;
use crate::render::photon::build_photon_maps;
use crate::render::ppm::{self, PpmError, PpmOptions, PpmState, Stop, StopReason};
use crate::render::{
    Cancelled, Control, IntegratorKind, Phase, Progress, RenderOutput, RenderParams, Scene, output,
    render_with_maps,
};
use std::ops::ControlFlow;
use tokio::sync::watch;

/// Why a job did not finish.
enum Failure {
    Cancelled,
    /// A progressive job gave way to another user between passes; it resumes later.
    Yielded,
    Error(String),
}

impl From<Cancelled> for Failure {
    fn from(_: Cancelled) -> Failure {
        Failure::Cancelled
    }
}

pub fn run_job(app: &Arc<App>, id: i64, cancel: &Arc<AtomicBool>) {
    let Some(row) = app.commit_job(id, |r| {
        r.status = Status::Running;
        r.started = Some(now());
        r.error = None;
    }) else {
        return; // deleted meanwhile
    };
    let t0 = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        // An uploaded scene's text lives in the store only (not in the live job table).
        let scene_json = app
            .store
            .scene_json(id)
            .map_err(|e| Failure::Error(format!("reading the job's scene: {e}")))?;
        if row.scene_bytes > 0 && scene_json.is_none() {
            return Err(Failure::Error(
                "the job's uploaded scene is gone from the store".into(),
            ));
        }
        execute(
            app,
            id,
            &row.params_json,
            scene_json.as_deref(),
            row.scene_name.as_deref(),
            cancel,
        )
    }));
    let result = match result {
        Ok(r) => r,
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(Failure::Error(format!("the renderer panicked: {msg}")))
        }
    };
    // Everything the render held is dropped: give it back before the outcome is published.
    give_memory_back();
    app.metrics.add_render_seconds(t0.elapsed().as_secs_f64());
    let requeue = matches!(result, Err(Failure::Cancelled)) && app.scheduler.is_stopping()
        || matches!(result, Err(Failure::Yielded));
    app.commit_job(id, |r| match &result {
        Ok(stats) => {
            r.status = Status::Done;
            r.finished = Some(now());
            r.stats_json = Some(stats.to_string());
        }
        Err(Failure::Cancelled | Failure::Yielded) if requeue => {
            r.status = Status::Queued;
            r.started = None;
        }
        Err(Failure::Cancelled | Failure::Yielded) => {
            r.status = Status::Cancelled;
            r.finished = Some(now());
        }
        Err(Failure::Error(e)) => {
            r.status = Status::Failed;
            r.finished = Some(now());
            r.error = Some(e.clone());
        }
    });
    if matches!(result, Err(Failure::Yielded)) {
        app.scheduler
            .requeue_front(id, row.user_id, row.memory_bytes);
    }
}

/// Return the freed heap of a finished render to the system. glibc keeps freed memory in
/// its arenas (one per render thread) for reuse, so a server that ran one large job would
/// otherwise stay at that job's peak for good.
fn give_memory_back() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Relative cost of each phase, for one progress fraction over the whole job.
fn phase_weights(p: &RenderParams, pixels: u64) -> [f64; 4] {
    let photons = (p.photons + p.caustic_photons) as f64;
    let samples = (pixels * p.spp as u64) as f64 * (1.0 + 1.5 * p.gather_rays as f64);
    [
        photons / 3e6,
        photons / 1e7,
        // ppm reads its maps by a fixed radius: no irradiance precomputation.
        if p.integrator == IntegratorKind::Ppm {
            0.0
        } else {
            p.photons as f64 * 0.35 * p.k as f64 / 2e7
        },
        samples / 3e6,
    ]
}

fn phase_index(phase: Phase) -> usize {
    match phase {
        Phase::BuildScene | Phase::PhotonTrace => 0,
        Phase::BuildMaps => 1,
        Phase::Precompute => 2,
        Phase::Render | Phase::Passes => 3,
    }
}

fn execute(
    app: &Arc<App>,
    id: i64,
    params_json: &str,
    scene_json: Option<&str>,
    scene_name: Option<&str>,
    cancel: &Arc<AtomicBool>,
) -> Result<Value, Failure> {
    let bad = |e: String| Failure::Error(e);
    let pj: ParamsJson =
        serde_json::from_str(params_json).map_err(|e| bad(format!("params: {e}")))?;
    let params = pj.to_params().map_err(|e| bad(e.message))?;
    let scene_value = match scene_json {
        Some(t) => Some(serde_json::from_str(t).map_err(|e| bad(format!("scene: {e}")))?),
        None => None,
    };
    let resolved = resolve_scene(
        &app.catalog,
        scene_value,
        scene_name.filter(|_| scene_json.is_none()),
    )
    .map_err(|e| bad(e.message))?;
    // The reference job's image; it may have been deleted since this job was submitted.
    let reference = match params.reference_job {
        Some(rid) => {
            let path = result_path(&app.config.data, rid, "exr");
            Some(output::read_exr(&path).map_err(|e| {
                bad(format!(
                    "reference job {rid}: its image cannot be read (was the job deleted?): {e}"
                ))
            })?)
        }
        None => None,
    };
    let p = &params.render;
    let width = p.width.unwrap_or(resolved.desc.camera.width) as u64;
    let height = p.height.unwrap_or(resolved.desc.camera.height) as u64;

    // One fraction over the phases, published monotone and at most every half percent.
    let weights = phase_weights(p, width * height);
    let total: f64 = weights.iter().sum::<f64>().max(1e-12);
    let live = app.jobs.live(id).ok_or_else(|| bad("job deleted".into()))?;
    let started = Instant::now();
    let last = Mutex::new((0.0f64, None::<&'static str>));
    // ppm: passes done, and the passes in all; a pass's phases fill in between.
    let passes = std::sync::atomic::AtomicU64::new(0);
    let iterations = if p.integrator == IntegratorKind::Ppm {
        p.iterations as f64
    } else {
        1.0
    };
    let on_progress = |pr: Progress| {
        let within = if pr.total > 0 {
            pr.done as f64 / pr.total as f64
        } else {
            1.0
        };
        let f = if pr.phase == Phase::Passes {
            passes.store(pr.done, std::sync::atomic::Ordering::Relaxed);
            within
        } else {
            let i = phase_index(pr.phase);
            let before: f64 = weights[..i].iter().sum();
            let in_pass = (before + weights[i] * within) / total;
            (passes.load(std::sync::atomic::Ordering::Relaxed) as f64 + in_pass) / iterations
        };
        let f = f.clamp(0.0, 0.999);
        let mut last = last.lock().unwrap_or_else(|e| e.into_inner());
        let phase = Some(pr.phase.name());
        if f < last.0 + 0.005 && phase == last.1 {
            return;
        }
        let f = f.max(last.0);
        *last = (f, phase);
        let elapsed = started.elapsed().as_secs_f64();
        let eta = (f > 0.02).then(|| elapsed * (1.0 - f) / f);
        live.send_modify(|s| {
            if s.status == Status::Running {
                s.progress = f;
                s.phase = phase;
                s.eta_seconds = eta;
            }
        });
    };
    let control = Control {
        cancel: Some(cancel),
        progress: Some(&on_progress),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(app.config.threads)
        .thread_name(move |i| format!("job-{id}-render-{i}"))
        .start_handler(|_| lower_priority())
        .build()
        .map_err(|e| bad(format!("starting render threads: {e}")))?;
    // Building the scene (its BVH) is a phase like the others: progress, cancel.
    let scene = pool.install(|| Scene::build_with(&resolved.desc, &control))?;
    let mut resume_note = None;
    let (out, outcome, key) = if p.integrator == IntegratorKind::Ppm {
        let scene_json = &resolved.text;
        let (out, note) = pool.install(|| {
            render_progressive(
                app,
                id,
                scene_json,
                &scene,
                &params,
                reference.as_ref(),
                &control,
                &live,
            )
        })?;
        resume_note = Some(note);
        (out, CacheOutcome::NotNeeded, None)
    } else {
        pool.install(|| -> Result<_, Failure> {
            let analysis = analyse(&scene, p);
            let pp = analysis.photon_params;
            let key = cache_key(&resolved, &pp);
            let (maps, outcome) = if pp.global_photons + pp.caustic_photons == 0 {
                let maps = build_photon_maps(&scene, &pp, &control)?;
                (Arc::new(maps), CacheOutcome::NotNeeded)
            } else {
                app.cache
                    .get_or_build(&key, cancel, || build_photon_maps(&scene, &pp, &control))?
            };
            let mut out = render_with_maps(&scene, &maps, p, &control)?;
            out.measure(reference.as_ref())
                .map_err(|e| bad(format!("reference job: {e}")))?;
            Ok((out, outcome, Some(key)))
        })?
    };
    drop(pool);

    let png = result_path(&app.config.data, id, "png");
    let exr = result_path(&app.config.data, id, "exr");
    output::write_images(&out.image, params.exposure, &png, Some(&exr))
        .map_err(|e| bad(format!("writing the result images: {e}")))?;

    let mut stats = serde_json::to_value(&out.stats).map_err(|e| bad(e.to_string()))?;
    if outcome == CacheOutcome::Hit {
        // The maps were traced by an earlier job: this one traced nothing.
        stats["times"]["photon_trace"] = json!(0.0);
        stats["times"]["build_maps"] = json!(0.0);
        let t = &out.stats.times;
        stats["times"]["total"] = json!(t.precompute + t.render);
    }
    // A job that did not use the cache (raytrace traces nothing; ppm traces its own maps)
    // traced what it reports; a cache hit traced nothing.
    let traced = match outcome {
        CacheOutcome::Hit => 0,
        CacheOutcome::Miss | CacheOutcome::NotNeeded => {
            out.stats.photons.global_emitted + out.stats.photons.caustic_emitted
        }
    };
    stats["photons"]["traced_by_this_job"] = json!(traced);
    stats["cache"] = match &key {
        Some(key) => json!({ "photon_maps": outcome.as_str(), "key": &key[..16] }),
        None => json!({ "photon_maps": outcome.as_str() }),
    };
    stats["params"]["exposure"] = json!(params.exposure);
    if let Some(note) = resume_note {
        stats["ppm_state"] = note;
    }
    Ok(stats)
}

/// A `ppm` job, pass by pass: after each pass the preview images and the running state
/// are written (atomically) and a preview is published; a job interrupted by a restart
/// resumes from its last saved pass, with the same bytes as an uninterrupted render. A
/// saved state that is corrupt (its checksum) or of other parameters is discarded, said in
/// the log, and the render starts from pass 0. Returns the output and what became of the
/// saved state (STATS.json's `ppm_state`).
#[allow(clippy::too_many_arguments)]
fn render_progressive(
    app: &Arc<App>,
    id: i64,
    scene_json: &str,
    scene: &Scene,
    params: &JobParams,
    reference: Option<&Image>,
    control: &Control,
    live: &watch::Sender<Snapshot>,
) -> Result<(RenderOutput, Value), Failure> {
    let p = &params.render;
    let state_path = result_path(&app.config.data, id, "ppmstate");
    let fingerprint = ppm::fingerprint(scene_json.as_bytes(), p);
    // A state that does not load or does not match is not ours to trust: start over.
    let (resume, note) = match std::fs::read(&state_path) {
        Err(_) => (None, json!({ "resumed_from_pass": 0 })),
        Ok(bytes) => match PpmState::load(&bytes[..]) {
            Ok(s) if s.fingerprint == fingerprint => {
                let note = json!({ "resumed_from_pass": s.passes });
                (Some(s), note)
            }
            Ok(_) => {
                let why = "the saved state is of other parameters";
                tracing::warn!(job = id, "{why}: starting again from pass 0");
                (None, json!({ "resumed_from_pass": 0, "discarded": why }))
            }
            Err(e) => {
                tracing::error!(
                    job = id,
                    "{}: {e}: starting again from pass 0",
                    state_path.display()
                );
                (
                    None,
                    json!({ "resumed_from_pass": 0, "discarded": e.to_string() }),
                )
            }
        },
    };
    let opts = PpmOptions {
        resume,
        reference,
        ..PpmOptions::new(Stop::after(p.iterations), fingerprint)
    };
    let png = result_path(&app.config.data, id, "png");
    let exr = result_path(&app.config.data, id, "exr");
    let mut on_pass = |state: &PpmState| {
        if state.passes >= p.iterations {
            // The last pass's image is the result, which `execute` writes.
            return ControlFlow::Continue(());
        }
        let wrote = output::write_images(&state.image(), params.exposure, &png, Some(&exr))
            .map_err(|e| e.to_string())
            .and_then(|_| state.save_file(&state_path).map_err(|e| e.to_string()));
        match wrote {
            // The render goes on: the next pass writes again, and the end is checked.
            Err(e) => tracing::warn!(job = id, "preview of pass {}: {e}", state.passes),
            Ok(()) => live.send_modify(|s| s.previews += 1),
        }
        if app.scheduler.should_yield(id) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    match ppm::render_ppm(scene, p, opts, control, &mut on_pass) {
        Ok(out)
            if out.output.stats.ppm.as_ref().map(|p| p.stopped_by) == Some(StopReason::Paused) =>
        {
            Err(Failure::Yielded)
        }
        Ok(out) => Ok((out.output, note)),
        Err(PpmError::Cancelled(_)) => Err(Failure::Cancelled),
        Err(PpmError::Input(e)) => Err(Failure::Error(e)),
    }
}

/// Render threads run at a lower priority (nice 10) than the API's threads, so that the
/// API answers in milliseconds while renders use every core.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority has no memory effects; on Linux, who = 0 is the calling thread.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}
