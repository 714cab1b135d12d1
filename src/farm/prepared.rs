//! A worker's copy of a task's job: its spec and scene read from the store and the scene
//! built, kept while the worker renders that job's tasks; the store's reads tried again
//! through a blip.

use std::sync::Arc;
use std::time::Duration;

use tokio::sync::watch;
use tokio::time::Instant;

use super::FarmError;
use super::records::JobSource;
use super::task::Kept;
use crate::render::{Control, Image, Scene};
use crate::server::jobs::JobSpec;
use crate::server::scenes::{ResolvedScene, SceneCatalog, resolve_uploaded};

/// A job's scene, built, and its spec: kept while the worker renders that job's tasks.
pub(super) struct Prepared {
    pub(super) job_id: i64,
    pub(super) scene: Arc<Scene>,
    pub(super) resolved: ResolvedScene,
    pub(super) spec: JobSpec,
    pub(super) size: (u32, u32),
    /// What its tasks found that the next ones reuse (initial radii, photon maps).
    pub(super) kept: Kept,
    /// The reference job's image, when the job has one.
    pub(super) reference: Option<Image>,
}

/// Why a worker could not make a task's job ready.
#[derive(Debug, PartialEq)]
pub(super) enum Unready {
    /// The task fails (and counts against the job's attempts).
    Failed(String),
    /// The worker is shutting down: it gives the task back, which is not a failure.
    ShuttingDown,
}

impl From<String> for Unready {
    fn from(why: String) -> Unready {
        Unready::Failed(why)
    }
}

/// `read` until it succeeds, fails for good, or `patience.0` has passed since the first
/// try (then its last error), trying again every `patience.1` while the store is out of
/// reach (`FarmError::is_transient`); a shutdown ends the waiting at once.
pub(super) async fn patiently<T, F, Fut>(
    patience: (Duration, Duration),
    what: &str,
    shutdown: &mut watch::Receiver<bool>,
    mut read: F,
) -> Result<T, Unready>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = Result<T, FarmError>>,
{
    let give_up = Instant::now() + patience.0;
    loop {
        match read().await {
            Ok(v) => return Ok(v),
            Err(e) if e.is_transient() && Instant::now() < give_up => {
                tracing::warn!("{what} (trying again): {e}");
                if told_to_stop_within(patience.1, shutdown).await {
                    return Err(Unready::ShuttingDown);
                }
            }
            Err(e) => return Err(Unready::Failed(format!("{what}: {e}"))),
        }
    }
}

/// Waits `pause` before a store's read is tried again; true if the worker is told to shut
/// down before or meanwhile (the wait then ends at once).
pub(super) async fn told_to_stop_within(
    pause: Duration,
    shutdown: &mut watch::Receiver<bool>,
) -> bool {
    let told = *shutdown.borrow();
    told || tokio::select! {
        _ = tokio::time::sleep(pause) => false,
        _ = shutdown.changed() => true,
    }
}

/// A job's spec and scene, the scene built.
pub(super) fn prepare(
    job_id: i64,
    source: &JobSource,
    spec: JobSpec,
    catalog: &SceneCatalog,
    pool: &rayon::ThreadPool,
) -> Result<Prepared, String> {
    let resolved = match (&source.scene_json, &source.scene_name) {
        (Some(text), _) => {
            let value = serde_json::from_str(text).map_err(|e| format!("the job's scene: {e}"))?;
            resolve_uploaded(value).map_err(|e| e.to_string())?
        }
        (None, Some(name)) => catalog.resolve(name).map_err(|e| e.to_string())?,
        (None, None) => return Err("the job has no scene".into()),
    };
    let scene = pool
        .install(|| Scene::build_with(&resolved.desc, &Control::none()))
        .map_err(|e| e.to_string())?;
    let camera = &resolved.desc.camera;
    let size = spec.render.resolution((camera.width, camera.height));
    Ok(Prepared {
        job_id,
        scene: Arc::new(scene),
        resolved,
        spec,
        size,
        kept: Kept::default(),
        reference: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts the reads, and fails the first `away` of them as a store out of reach.
    async fn read(calls: &std::cell::Cell<u32>, away: u32) -> Result<u32, FarmError> {
        calls.set(calls.get() + 1);
        match calls.get() <= away {
            true => Err(FarmError::Db(sqlx::Error::PoolTimedOut)),
            false => Ok(calls.get()),
        }
    }

    /// A blip is waited out; a store that stays away, or a job that is gone, is an error
    /// (the task's failure), so no task is claimed and given back forever.
    #[tokio::test]
    async fn a_blip_is_waited_out_and_a_lasting_failure_is_the_task_s() {
        let calls = std::cell::Cell::new(0);
        let pause = Duration::from_millis(1);
        let (_tx, mut shutdown) = watch::channel(false);
        let long = (Duration::from_secs(60), pause);
        let got = patiently(long, "r", &mut shutdown, || read(&calls, 2)).await;
        assert_eq!(got, Ok(3));
        calls.set(0);
        let got = patiently((Duration::ZERO, pause), "r", &mut shutdown, || {
            read(&calls, 5)
        });
        assert!(matches!(got.await, Err(Unready::Failed(_))));
        assert_eq!(calls.get(), 1);
        calls.set(0);
        let gone = patiently(long, "reading the job", &mut shutdown, || async {
            calls.set(calls.get() + 1);
            Err::<u32, _>(FarmError::NoSuchJob(3))
        });
        let why = "reading the job: no job 3".to_string();
        assert_eq!(gone.await, Err(Unready::Failed(why)));
        assert_eq!(calls.get(), 1);
    }

    /// A worker told to shut down while the store is away stops waiting at once and says
    /// so, rather than failing the task (which would count against the job's attempts).
    #[tokio::test(start_paused = true)]
    async fn a_shutdown_ends_the_waiting_without_failing_the_task() {
        let calls = std::cell::Cell::new(0);
        let (tx, mut shutdown) = watch::channel(false);
        let patience = (Duration::from_secs(3600), Duration::from_secs(1));
        let waiting = patiently(patience, "r", &mut shutdown, || read(&calls, u32::MAX));
        let stop = async {
            tokio::time::sleep(Duration::from_millis(4500)).await;
            tx.send_replace(true);
            std::future::pending::<()>().await
        };
        let got = tokio::select! {
            got = waiting => got,
            _ = stop => unreachable!(),
        };
        assert_eq!(got, Err(Unready::ShuttingDown));
        assert_eq!(calls.get(), 5);
        let mut stopped = tx.subscribe();
        let got = patiently(patience, "r", &mut stopped, || read(&calls, u32::MAX)).await;
        assert_eq!(got, Err(Unready::ShuttingDown));
    }
}
