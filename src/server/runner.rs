//! Running one job on its own rayon pool: read its stored spec and scene, build the scene,
//! call the engine's one entry point (`render::run`) with the photon-map cache as its map
//! source, write the images, and commit the outcome. Progress goes to the job's watch
//! channel; a panic inside the render fails that job only. The render itself, its
//! progress and its per-pass saves: `render_job.rs`.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use serde::Serialize;

use super::App;
use super::cache::CacheOutcome;
use super::jobs::JobSpec;
use super::render_job::{JobRender, ResumeNote};
use super::results::result_path;
use super::scenes::{ResolvedScene, SceneRefError, resolve_uploaded};
use super::store::{JobRow, Status, now};
use crate::render::stats::RenderStats;
use crate::render::{Cancelled, Image, RenderError, output};

/// Why a job did not finish.
pub(super) enum Failure {
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

impl From<RenderError> for Failure {
    fn from(e: RenderError) -> Failure {
        match e {
            RenderError::Cancelled(_) => Failure::Cancelled,
            e => Failure::Error(e.to_string()),
        }
    }
}

/// A finished job's STATS.json: the engine's, and what the server adds.
#[derive(Serialize)]
pub(super) struct JobStats {
    #[serde(flatten)]
    pub render: RenderStats,
    pub cache: CacheReport,
    /// A progressive job: whether it resumed from a saved state.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ppm_state: Option<ResumeNote>,
}

/// Where the job's photon maps came from.
#[derive(Serialize)]
pub(super) struct CacheReport {
    /// `hit`, `miss`, or `not_needed` (no maps, or a progressive job's own per pass).
    pub photon_maps: &'static str,
    /// The cache key's first 16 hex digits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub key: Option<String>,
}

impl CacheReport {
    pub fn of(used: Option<(CacheOutcome, String)>) -> CacheReport {
        match used {
            Some((outcome, key)) => CacheReport {
                photon_maps: outcome.as_str(),
                key: Some(key[..16].to_string()),
            },
            None => CacheReport {
                photon_maps: CacheOutcome::NotNeeded.as_str(),
                key: None,
            },
        }
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
    let result =
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(app, &row, cancel)));
    let result = result.unwrap_or_else(|panic| {
        let msg = panic
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown panic".into());
        Err(Failure::Error(format!("the renderer panicked: {msg}")))
    });
    // Everything the render held is dropped: give it back before the outcome is published.
    give_memory_back();
    app.metrics.add_render_seconds(t0.elapsed().as_secs_f64());
    commit_outcome(app, &row, result);
}

/// Record how the job ended: done with its stats, failed with the reason, cancelled, or
/// queued again (the server is stopping, or the job gave way between passes).
fn commit_outcome(app: &Arc<App>, row: &JobRow, result: Result<String, Failure>) {
    let requeue = matches!(result, Err(Failure::Cancelled)) && app.scheduler.is_stopping()
        || matches!(result, Err(Failure::Yielded));
    app.commit_job(row.id, |r| match &result {
        Ok(stats) => {
            r.status = Status::Done;
            r.finished = Some(now());
            r.stats_json = Some(stats.clone());
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
            .requeue_front(row.id, row.user_id, row.memory_bytes);
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

/// Render a job and write its images; its stats as the text stored and served.
fn execute(app: &Arc<App>, row: &JobRow, cancel: &Arc<AtomicBool>) -> Result<String, Failure> {
    let spec = JobSpec::from_stored(&row.params_json).map_err(Failure::Error)?;
    let scene = job_scene(app, row)?;
    let reference = reference_image(app, spec.reference_job)?;
    let job = JobRender {
        app,
        id: row.id,
        spec: &spec,
        scene: &scene,
        reference: reference.as_ref(),
        cancel,
    };
    let (out, cache, ppm_state) = job.render()?;
    let png = result_path(&app.config.data, row.id, "png");
    let exr = result_path(&app.config.data, row.id, "exr");
    output::write_images(&out.image, spec.exposure, &png, Some(&exr))
        .map_err(|e| Failure::Error(format!("writing the result images: {e}")))?;
    let mut render = out.stats;
    render.params.exposure = Some(spec.exposure);
    let stats = JobStats {
        render,
        cache,
        ppm_state,
    };
    serde_json::to_string(&stats).map_err(|e| Failure::Error(e.to_string()))
}

/// The job's scene: its uploaded text from the store, or the built-in one catalogued at
/// start.
fn job_scene(app: &Arc<App>, row: &JobRow) -> Result<ResolvedScene, Failure> {
    let failed = |e: SceneRefError| match e {
        SceneRefError::Invalid { path, message } => Failure::Error(format!("{path}: {message}")),
        SceneRefError::Internal(m) => Failure::Error(m),
    };
    let text = app
        .store
        .scene_json(row.id)
        .map_err(|e| Failure::Error(format!("reading the job's scene: {e}")))?;
    match (text, &row.scene_name) {
        (Some(text), _) => {
            let value = serde_json::from_str(&text)
                .map_err(|e| Failure::Error(format!("the job's scene: {e}")))?;
            resolve_uploaded(value).map_err(failed)
        }
        (None, _) if row.scene_bytes > 0 => Err(Failure::Error(
            "the job's uploaded scene is gone from the store".into(),
        )),
        (None, Some(name)) => app.catalog.resolve(name).map_err(failed),
        (None, None) => Err(Failure::Error("the job has no scene".into())),
    }
}

/// The reference job's image; it may have been deleted since this job was submitted.
fn reference_image(app: &Arc<App>, reference_job: Option<i64>) -> Result<Option<Image>, Failure> {
    let Some(rid) = reference_job else {
        return Ok(None);
    };
    let path = result_path(&app.config.data, rid, "exr");
    output::read_exr(&path).map(Some).map_err(|e| {
        Failure::Error(format!(
            "reference job {rid}: its image cannot be read (was the job deleted?): {e}"
        ))
    })
}
