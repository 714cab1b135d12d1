//! One job's render on its own pool: progress published as one monotone fraction, the
//! photon-map cache as the engine's map source, and (progressive jobs) a preview and the
//! saved state after every pass, so that a restart resumes from the last pass with the same
//! bytes as an uninterrupted render.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;
use tokio::sync::watch;

use super::App;
use super::cache::CachedMaps;
use super::jobs::JobSpec;
use super::results::result_path;
use super::runner::{CacheReport, Failure};
use super::scenes::ResolvedScene;
use super::state::Snapshot;
use super::store::Status;
use crate::render::ppm::PpmState;
use crate::render::{
    Control, Image, Inputs, Progress, ProgressModel, RenderOutput, Scene, fingerprint, output, run,
};

/// What became of a progressive job's saved state (STATS.json's `ppm_state`).
#[derive(Serialize, Clone, Debug)]
pub(super) struct ResumeNote {
    pub resumed_from_pass: u32,
    /// Why a saved state was not used (corrupt, or of other parameters).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub discarded: Option<String>,
}

/// A job ready to render.
pub(super) struct JobRender<'a> {
    pub app: &'a Arc<App>,
    pub id: i64,
    pub spec: &'a JobSpec,
    pub scene: &'a ResolvedScene,
    pub reference: Option<&'a Image>,
    pub cancel: &'a Arc<AtomicBool>,
}

impl JobRender<'_> {
    /// Build the scene and render it on the job's pool.
    pub fn render(&self) -> Result<(RenderOutput, CacheReport, Option<ResumeNote>), Failure> {
        let app = self.app;
        let live = app
            .jobs
            .live(self.id)
            .ok_or_else(|| Failure::Error("job deleted".into()))?;
        let camera = &self.scene.desc.camera;
        let (w, h) = self.spec.render.resolution((camera.width, camera.height));
        let publish = Publisher::new(&self.spec.render, w as u64 * h as u64, &live);
        let on_progress = |p: Progress| publish.progress(p);
        let control = Control {
            cancel: Some(self.cancel),
            progress: Some(&on_progress),
        };
        let id = self.id;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(app.config.threads)
            .thread_name(move |i| format!("job-{id}-render-{i}"))
            .start_handler(|_| lower_priority())
            .build()
            .map_err(|e| Failure::Error(format!("starting render threads: {e}")))?;
        // Building the scene (its BVH) is a phase like the others: progress, cancel.
        let scene = pool.install(|| Scene::build_with(&self.scene.desc, &control))?;
        publish.scene_built(&scene, &self.spec.render, w as u64 * h as u64);
        let maps = CachedMaps {
            cache: &app.cache,
            scene_without_camera: &self.scene.without_camera,
            cancel: self.cancel,
            used: Mutex::new(None),
        };
        let (resume, note) = self.saved_state();
        let inputs = Inputs {
            maps: &maps,
            reference: self.reference,
            resume,
            scene_key: self.scene.text.as_bytes(),
            piece: None,
            rows: None,
            choice: None,
        };
        let mut on_pass = |state: &PpmState| {
            publish.pass_done(state.elapsed() + state.choosing());
            self.after_pass(state, &live)
        };
        let out =
            pool.install(|| run(&scene, &self.spec.render, inputs, &control, &mut on_pass))?;
        if out.paused() {
            return Err(Failure::Yielded);
        }
        let used = maps.used.into_inner().unwrap_or_else(|e| e.into_inner());
        Ok((out, CacheReport::of(used), note))
    }

    /// A progressive job's saved state, if it has one that is its own: a state that does
    /// not load (its checksum) or is of other parameters is discarded, said in the log,
    /// and the render starts from pass 0.
    fn saved_state(&self) -> (Option<PpmState>, Option<ResumeNote>) {
        if !self.spec.render.is_progressive() {
            return (None, None);
        }
        let path = result_path(&self.app.config.data, self.id, "ppmstate");
        let note = |pass, discarded| {
            Some(ResumeNote {
                resumed_from_pass: pass,
                discarded,
            })
        };
        let Ok(bytes) = std::fs::read(&path) else {
            return (None, note(0, None));
        };
        let expected = fingerprint(self.scene.text.as_bytes(), &self.spec.render);
        match PpmState::load(&bytes[..]) {
            Ok(s) if s.fingerprint == expected => {
                let pass = s.passes;
                (Some(s), note(pass, None))
            }
            Ok(_) => {
                let why = "the saved state is of other parameters";
                tracing::warn!(job = self.id, "{why}: starting again from pass 0");
                (None, note(0, Some(why.to_string())))
            }
            Err(e) => {
                tracing::error!(
                    job = self.id,
                    "{}: {e}: starting again from pass 0",
                    path.display()
                );
                (None, note(0, Some(e.to_string())))
            }
        }
    }

    /// After a progressive pass: the preview images and the state, each replaced
    /// atomically, a `preview` event, and whether to give way to another user.
    fn after_pass(&self, state: &PpmState, live: &watch::Sender<Snapshot>) -> ControlFlow<()> {
        let last = self.spec.render.stop().and_then(|s| s.iterations);
        if last.is_some_and(|last| state.passes >= last) {
            // The last pass's image is the result, which the runner writes.
            return ControlFlow::Continue(());
        }
        let data = &self.app.config.data;
        let (png, exr) = (
            result_path(data, self.id, "png"),
            result_path(data, self.id, "exr"),
        );
        let state_path = result_path(data, self.id, "ppmstate");
        let wrote = output::write_images(&state.image(), self.spec.exposure, &png, Some(&exr))
            .map_err(|e| e.to_string())
            .and_then(|_| state.save_file(&state_path).map_err(|e| e.to_string()));
        match wrote {
            // The render goes on: the next pass writes again, and the end is checked.
            Err(e) => tracing::warn!(job = self.id, "preview of pass {}: {e}", state.passes),
            Ok(()) => live.send_modify(|s| s.previews += 1),
        }
        if self.app.scheduler.should_yield(self.id) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// Publishes a job's progress: one fraction over the phases (the engine's cost model),
/// monotone, at most every half percent or on a change of phase, with an ETA.
struct Publisher<'a> {
    /// The spec's model, then (once the scene is built) that of what will render it.
    model: Mutex<ProgressModel>,
    live: &'a watch::Sender<Snapshot>,
    started: Instant,
    /// Progressive passes done (the last `passes` report).
    passes: AtomicU64,
    /// The engine's seconds of passes and of `auto`'s pilot (its time limit's clock, which
    /// leaves out the scene build, the writes between passes and the time before a resume)
    /// at an instant: from the scene's build (the pilot runs next, and reports no
    /// progress), set again after every pass.
    pass_clock: Mutex<Option<(f64, Instant)>>,
    last: Mutex<(f64, Option<&'static str>)>,
}

impl<'a> Publisher<'a> {
    fn new(spec: &crate::spec::RenderSpec, pixels: u64, live: &'a watch::Sender<Snapshot>) -> Self {
        Publisher {
            model: Mutex::new(ProgressModel::new(spec, pixels)),
            live,
            started: Instant::now(),
            passes: AtomicU64::new(0),
            pass_clock: Mutex::new(None),
            last: Mutex::new((0.0, None)),
        }
    }

    /// The scene is built: count progress by what will render `spec` on it (an `auto`
    /// job's one photon render, [`ProgressModel::for_scene`]).
    fn scene_built(&self, scene: &Scene, spec: &crate::spec::RenderSpec, pixels: u64) {
        *self.model.lock().unwrap_or_else(|e| e.into_inner()) =
            ProgressModel::for_scene(scene, spec, pixels);
        let mut clock = self.pass_clock.lock().unwrap_or_else(|e| e.into_inner());
        clock.get_or_insert_with(|| (0.0, Instant::now()));
    }

    /// A pass ended, `seconds` of passes in all.
    fn pass_done(&self, seconds: f64) {
        *self.pass_clock.lock().unwrap_or_else(|e| e.into_inner()) =
            Some((seconds, Instant::now()));
    }

    /// The engine's seconds of passes and pilot by now (0 before the scene is built).
    fn pass_seconds(&self) -> f64 {
        let clock = self.pass_clock.lock().unwrap_or_else(|e| e.into_inner());
        clock.map_or(0.0, |(seconds, at)| seconds + at.elapsed().as_secs_f64())
    }

    fn progress(&self, p: Progress) {
        if p.phase == crate::render::Phase::Passes {
            self.passes.store(p.done, Ordering::Relaxed);
        }
        let passes = self.passes.load(Ordering::Relaxed);
        let pass_seconds = self.pass_seconds();
        let f = (self.model.lock().unwrap_or_else(|e| e.into_inner())).fraction(
            p,
            passes,
            pass_seconds,
        );
        let f = f.clamp(0.0, 0.999);
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let phase = Some(p.phase.name());
        if f < last.0 + 0.005 && phase == last.1 {
            return;
        }
        let f = f.max(last.0);
        *last = (f, phase);
        let elapsed = self.started.elapsed().as_secs_f64();
        let eta = (f > 0.02).then(|| elapsed * (1.0 - f) / f);
        self.live.send_modify(|s| {
            if s.status == Status::Running {
                s.progress = f;
                s.phase = phase;
                s.eta_seconds = eta;
            }
        });
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A timed job's clock runs from the scene's build, not from its first pass: `auto`'s
    /// pilot runs in between, reports no progress, and its time limit counts it.
    #[test]
    fn the_pass_clock_runs_from_the_scene_s_build() {
        let (live, _rx) = watch::channel(Snapshot {
            status: Status::Running,
            progress: 0.0,
            phase: None,
            eta_seconds: None,
            previews: 0,
            error: None,
        });
        // A job's params as stored: the default integrator (`auto`) under a time limit.
        let spec = JobSpec::from_stored(r#"{"time_limit": 4}"#).unwrap().render;
        assert_eq!(spec.stop().and_then(|s| s.time_limit), Some(4.0));
        let scene = Scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.json"),
        )
        .unwrap();
        let publish = Publisher::new(&spec, 64 * 64, &live);
        assert_eq!(publish.pass_seconds(), 0.0);
        publish.scene_built(&scene, &spec, 64 * 64);
        let (a, b) = (publish.pass_seconds(), publish.pass_seconds());
        assert!(a > 0.0 && b >= a, "{a} then {b}");
        // A pass sets the clock to the engine's own seconds.
        publish.pass_done(1.5);
        assert!(publish.pass_seconds() >= 1.5);
    }
}
