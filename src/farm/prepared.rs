//! A worker's copy of a task's job: its spec and scene read from the store and the scene
//! built, kept while the worker renders that job's tasks; and why that may fail, which
//! decides whether the task failed or is given back.

use std::sync::Arc;

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

/// Why a task's job could not be prepared.
#[derive(Debug, PartialEq)]
pub(super) enum Unprepared {
    /// The job cannot render (its spec, its scene, its reference): a failure of the task.
    Job(String),
    /// The store was out of reach: no fault of the task's.
    StoreAway(String),
}

impl Unprepared {
    /// A store error while reading `what`.
    pub(super) fn of(e: FarmError, what: &str) -> Unprepared {
        let text = format!("{what}: {e}");
        match e.is_transient() {
            true => Unprepared::StoreAway(text),
            false => Unprepared::Job(text),
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

    /// A store out of reach gives the task back; a job that cannot render fails it.
    #[test]
    fn a_store_away_is_not_the_task_s_failure() {
        let away = Unprepared::of(FarmError::Db(sqlx::Error::PoolTimedOut), "reading the job");
        assert!(matches!(away, Unprepared::StoreAway(_)), "{away:?}");
        let gone = Unprepared::of(FarmError::NoSuchJob(3), "reading the job");
        assert_eq!(gone, Unprepared::Job("reading the job: no job 3".into()));
    }
}
