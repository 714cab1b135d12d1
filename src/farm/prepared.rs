//! A worker's copy of a task's job: its spec and scene read from the store and the scene
//! built, kept while the worker renders that job's tasks; the store's reads tried again
//! through a blip.

use std::sync::Arc;
use std::time::Duration;

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

/// `read` until it succeeds, fails for good, or `patience.0` has passed since the first
/// try (then its last error), trying again every `patience.1` while the store is out of
/// reach (`FarmError::is_transient`).
pub(super) async fn patiently<T, F, Fut>(
    patience: (Duration, Duration),
    what: &str,
    mut read: F,
) -> Result<T, String>
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
                tokio::time::sleep(patience.1).await;
            }
            Err(e) => return Err(format!("{what}: {e}")),
        }
    }
}

/// A job's spec and scene, the scene built.
pub(super) fn prepare(
    job_id: i64,
    source: &JobSource,
    catalog: &SceneCatalog,
    pool: &rayon::ThreadPool,
) -> Result<Prepared, String> {
    let spec = JobSpec::from_stored(&source.params_json)?;
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
        let got = patiently((Duration::from_secs(60), pause), "r", || read(&calls, 2)).await;
        assert_eq!(got, Ok(3));
        calls.set(0);
        let got = patiently((Duration::ZERO, pause), "r", || read(&calls, 5)).await;
        assert_eq!((got.is_err(), calls.get()), (true, 1));
        calls.set(0);
        let gone = patiently(
            (Duration::from_secs(60), pause),
            "reading the job",
            || async {
                calls.set(calls.get() + 1);
                Err::<u32, _>(FarmError::NoSuchJob(3))
            },
        );
        assert_eq!(gone.await, Err("reading the job: no job 3".into()));
        assert_eq!(calls.get(), 1);
    }
}
