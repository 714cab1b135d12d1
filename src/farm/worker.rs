//! `photonbox worker`: a render box of the farm. It claims a task (waking on NOTIFY, with a
//! poll as fallback), renders its unit on its own rayon pool while a heartbeat extends the
//! lease, and hands the result in; the worker whose completion is the job's last merges
//! the job's image. A cancel (NOTIFY on the cancel channel) or a lost lease stops the
//! render at its next check; a shutdown (SIGTERM, Ctrl-C) stops it and gives the task
//! back. Nothing here is needed for correctness but the lease: a worker that stops
//! heartbeating, for whatever reason, loses its task to another after the lease.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use tokio::sync::watch;

use super::outcome::{job_stats, merge};
use super::prepared::{Prepared, Unready, patiently, prepare, told_to_stop_within};
use super::queue::CANCEL_CHANNEL;
use super::records::JobImages;
use super::task::{UnitResult, render_unit};
use super::{Completion, FarmError, Lease, Queue};
use crate::render::{Image, RenderError, output};
use crate::server::jobs::JobSpec;
use crate::server::scenes::SceneCatalog;

/// How long a worker sleeps between claims when no NOTIFY wakes it (a notification lost
/// while its listener reconnected, or a lease that expired and nobody announced).
const POLL: Duration = Duration::from_secs(2);

/// How long a worker keeps trying to hand in a finished result while the store is out of
/// reach, and how often.
const HAND_IN_PATIENCE: Duration = Duration::from_secs(300);
const RETRY: Duration = Duration::from_millis(500);

/// Everything `photonbox worker` can be told.
#[derive(Clone, Debug)]
pub struct WorkerConfig {
    pub store: String,
    /// The worker's name in the registry (unique in the farm).
    pub id: String,
    pub threads: usize,
    /// Memory this worker's renders may take: it claims only tasks that fit.
    pub memory_bytes: u64,
    pub scenes: PathBuf,
    /// A claim's lease; heartbeats renew it three times per lease.
    pub lease: Duration,
}

/// Run a worker until `shutdown` turns true; `joined` is given its queue once it has
/// joined the farm (its probes answer from then on).
pub async fn run_worker(
    cfg: WorkerConfig,
    mut shutdown: watch::Receiver<bool>,
    joined: watch::Sender<Option<Queue>>,
) -> anyhow::Result<()> {
    let Some((queue, mut listener)) = join_the_farm(&cfg, &mut shutdown).await? else {
        return Ok(());
    };
    joined.send_replace(Some(queue.clone()));
    let scenes = cfg.scenes.clone();
    let catalog = Arc::new(tokio::task::spawn_blocking(move || SceneCatalog::load(scenes)).await?);
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(cfg.threads)
            .thread_name(|i| format!("worker-render-{i}"))
            .build()?,
    );
    let mut prepared: Option<Arc<Prepared>> = None;
    tracing::info!(worker = cfg.id, "worker started");
    while !*shutdown.borrow() {
        match queue.claim(&cfg.id, cfg.memory_bytes, cfg.lease).await {
            Ok(Some(lease)) => {
                let task = Task {
                    queue: &queue,
                    cfg: &cfg,
                    catalog: &catalog,
                    pool: &pool,
                };
                prepared = task
                    .run(lease, prepared, &mut listener, &mut shutdown)
                    .await;
                continue;
            }
            Ok(None) => {}
            Err(e) => tracing::warn!("claiming a task: {e}"),
        }
        let _ = queue.worker_alive(&cfg.id).await;
        tokio::select! {
            n = listener.recv() => if n.is_err() { tokio::time::sleep(RETRY).await },
            _ = tokio::time::sleep(POLL) => {}
            _ = shutdown.changed() => {}
        }
    }
    let _ = queue.deregister_worker(&cfg.id).await;
    tracing::info!(worker = cfg.id, "worker stopped");
    Ok(())
}

/// Connect to the store, register and listen; a store out of reach (not started yet, or
/// restarting) is waited for, a store that refuses us (a bad URL, an unknown role) is an
/// error. None: shut down while waiting.
async fn join_the_farm(
    cfg: &WorkerConfig,
    shutdown: &mut watch::Receiver<bool>,
) -> anyhow::Result<Option<(Queue, sqlx::postgres::PgListener)>> {
    loop {
        let joined = async {
            let queue = Queue::connect(&cfg.store, 4).await?;
            queue
                .register_worker(&cfg.id, cfg.threads as u32, cfg.memory_bytes)
                .await?;
            let listener = queue.listener().await?;
            Ok::<_, FarmError>((queue, listener))
        }
        .await;
        match joined {
            Ok(joined) => return Ok(Some(joined)),
            Err(e) if e.is_transient() => {
                tracing::warn!("the store is out of reach (trying again): {e}");
            }
            Err(e) => return Err(e).context("joining the farm's store"),
        }
        tokio::select! {
            _ = tokio::time::sleep(POLL) => {}
            _ = shutdown.changed() => return Ok(None),
        }
    }
}

struct Task<'a> {
    queue: &'a Queue,
    cfg: &'a WorkerConfig,
    catalog: &'a Arc<SceneCatalog>,
    pool: &'a Arc<rayon::ThreadPool>,
}

impl Task<'_> {
    /// Render a leased task to its end (or its loss); returns the job prepared for the next
    /// task.
    async fn run(
        &self,
        lease: Lease,
        prepared: Option<Arc<Prepared>>,
        listener: &mut sqlx::postgres::PgListener,
        shutdown: &mut watch::Receiver<bool>,
    ) -> Option<Arc<Prepared>> {
        let job = match prepared.filter(|p| p.job_id == lease.job_id) {
            Some(p) => p,
            None => match self.prepare(lease.job_id, shutdown).await {
                Ok(p) => Arc::new(p),
                Err(Unready::Failed(e)) => {
                    self.report_failure(&lease, &e).await;
                    return None;
                }
                Err(Unready::ShuttingDown) => {
                    self.give_back(&lease).await;
                    return None;
                }
            },
        };
        let cancel = Arc::new(AtomicBool::new(false));
        let (job2, cancel2, pool, unit) =
            (job.clone(), cancel.clone(), self.pool.clone(), lease.unit);
        let mut render = tokio::task::spawn_blocking(move || {
            pool.install(|| {
                let key = job2.resolved.text.as_bytes();
                render_unit(
                    &job2.scene,
                    &job2.spec.render,
                    (key, job2.reference.as_ref()),
                    unit,
                    &job2.kept,
                    &cancel2,
                )
            })
        });
        let mut beat = tokio::time::interval(self.cfg.lease / 3);
        beat.tick().await;
        let mut releasing = false;
        let result = loop {
            tokio::select! {
                r = &mut render => break r,
                _ = beat.tick() => match self.queue.heartbeat(&lease, self.cfg.lease).await {
                    Ok(()) => { let _ = self.queue.worker_alive(&self.cfg.id).await; }
                    Err(FarmError::Lost(why)) => {
                        tracing::warn!(job = lease.job_id, seq = lease.seq, "{why}: stopping");
                        cancel.store(true, Ordering::Relaxed);
                    }
                    Err(e) => tracing::warn!("heartbeat: {e}"),
                },
                n = listener.recv() => match n {
                    Ok(n) if n.channel() == CANCEL_CHANNEL
                        && n.payload() == lease.job_id.to_string() =>
                    {
                        cancel.store(true, Ordering::Relaxed);
                    }
                    Ok(_) => {}
                    // The store is out of reach: the heartbeat says what that means for
                    // the lease; listen again a little later.
                    Err(_) => tokio::time::sleep(RETRY).await,
                },
                _ = shutdown.changed() => {
                    releasing = true;
                    cancel.store(true, Ordering::Relaxed);
                }
            }
        };
        match result {
            Ok(Ok(result)) => self.hand_in(&lease, &job, &result, shutdown).await,
            Ok(Err(RenderError::Cancelled(_))) if releasing => self.give_back(&lease).await,
            Ok(Err(RenderError::Cancelled(_))) => {}
            Ok(Err(e)) => self.report_failure(&lease, &e.to_string()).await,
            Err(panic) => {
                self.report_failure(&lease, &format!("the renderer panicked: {panic}"))
                    .await
            }
        }
        Some(job)
    }

    /// Read the job's spec, its reference's image (if it has one: a reference deleted since
    /// fails the task before the scene is built for nothing) and its scene, and build the
    /// scene (its BVH) on the worker's pool. A store out of reach is tried again for half
    /// a lease (the lease holds meanwhile) before the task counts a failure: a blip costs
    /// nothing, a store that keeps failing the read fails the job after its attempts, as
    /// any other failure. A shutdown meanwhile gives the task back.
    async fn prepare(
        &self,
        job_id: i64,
        shutdown: &mut watch::Receiver<bool>,
    ) -> Result<Prepared, Unready> {
        let patience = (self.cfg.lease / 2, RETRY);
        let read = || self.queue.job_source(job_id);
        let source = patiently(patience, "reading the job", shutdown, read).await?;
        let spec = JobSpec::from_stored(&source.params_json)?;
        let reference = match spec.reference_job {
            Some(rid) => Some(self.reference(rid, shutdown).await?),
            None => None,
        };
        let (catalog, pool) = (self.catalog.clone(), self.pool.clone());
        let build = move || prepare(job_id, &source, spec, &catalog, &pool);
        let mut prepared = tokio::task::spawn_blocking(build)
            .await
            .map_err(|e| e.to_string())??;
        prepared.reference = reference;
        Ok(prepared)
    }

    /// Reference job `rid`'s image, from the store; it may have been deleted since the
    /// job was submitted.
    async fn reference(
        &self,
        rid: i64,
        shutdown: &mut watch::Receiver<bool>,
    ) -> Result<Image, Unready> {
        let gone = |e: String| {
            format!("reference job {rid}: its image cannot be read (was the job deleted?): {e}")
        };
        let patience = (self.cfg.lease / 2, RETRY);
        let read = || self.queue.job_image(rid, true);
        let bytes = match patiently(patience, "reading the reference", shutdown, read).await {
            Ok(bytes) => bytes,
            Err(Unready::Failed(e)) => return Err(gone(e).into()),
            Err(Unready::ShuttingDown) => return Err(Unready::ShuttingDown),
        };
        let bytes = bytes.ok_or_else(|| gone("no image".into()))?;
        Ok(output::decode_exr(&bytes).map_err(|e| gone(e.to_string()))?)
    }

    /// Give a task back to the queue unrendered (the worker is shutting down).
    async fn give_back(&self, lease: &Lease) {
        if let Err(e) = self.queue.release(lease).await {
            tracing::warn!("giving the task back: {e}");
        }
    }

    async fn report_failure(&self, lease: &Lease, reason: &str) {
        tracing::warn!(job = lease.job_id, seq = lease.seq, "task failed: {reason}");
        if let Err(e) = self.queue.fail(lease, reason).await {
            tracing::warn!("reporting the failure: {e}");
        }
    }

    /// Hand the result in; the last task's worker merges the job. A store out of reach is
    /// tried again (the lease may still hold, and if it has passed on, the fence refuses
    /// the result and says so in the counters) until [`HAND_IN_PATIENCE`], or until the
    /// worker is told to shut down: then the result is dropped, and the task, its lease
    /// run out, is rendered again elsewhere (to the same bytes).
    async fn hand_in(
        &self,
        lease: &Lease,
        job: &Prepared,
        result: &UnitResult,
        shutdown: &mut watch::Receiver<bool>,
    ) {
        let give_up = tokio::time::Instant::now() + HAND_IN_PATIENCE;
        let stats = Some(result.stats_json.as_str());
        let completed = loop {
            match self.queue.complete(lease, &result.bytes, stats).await {
                Err(FarmError::Db(e)) if tokio::time::Instant::now() < give_up => {
                    tracing::warn!(
                        job = lease.job_id,
                        "handing in a result (trying again): {e}"
                    );
                    if told_to_stop_within(RETRY, shutdown).await {
                        tracing::warn!(job = lease.job_id, "shutting down: result dropped");
                        return;
                    }
                }
                other => break other,
            }
        };
        match completed {
            Ok(Completion::Accepted { job_done: true }) => {
                if let Err(e) = self.finish(lease.job_id, job).await {
                    tracing::error!(job = lease.job_id, "merging the job: {e}");
                    let _ = self.queue.fail_job(lease.job_id, &e).await;
                }
            }
            Ok(Completion::Accepted { job_done: false }) => {}
            Ok(Completion::Refused(why)) => {
                tracing::warn!(job = lease.job_id, seq = lease.seq, "result refused: {why}");
            }
            Err(e) => tracing::warn!(job = lease.job_id, "handing in a result: {e}"),
        }
    }

    /// Merge the job's results in task order (measured against its reference, if it has
    /// one), and store its images and stats.
    async fn finish(&self, job_id: i64, job: &Prepared) -> Result<(), String> {
        let results = self
            .queue
            .results(job_id)
            .await
            .map_err(|e| e.to_string())?;
        let stats: Vec<Option<String>> = results.iter().map(|r| r.stats_json.clone()).collect();
        let units = results
            .into_iter()
            .map(|r| r.result.map(|bytes| (r.unit, bytes)))
            .collect::<Option<Vec<_>>>()
            .ok_or("a task of a finished job has no result")?;
        let (size, exposure) = (job.size, job.spec.exposure);
        let reference = job.reference.clone();
        let (images, errors) = tokio::task::spawn_blocking(move || {
            let merged = merge(size, &units, reference.as_ref())?;
            let images = JobImages {
                exr: output::encode_exr(&merged.image).map_err(|e| e.to_string())?,
                png: output::encode_png(&merged.image, exposure).map_err(|e| e.to_string())?,
            };
            Ok::<_, String>((images, merged.errors))
        })
        .await
        .map_err(|e| e.to_string())??;
        let stats = job_stats(&stats, &errors).to_string();
        self.queue
            .finish_job(job_id, &images, &stats)
            .await
            .map_err(|e| e.to_string())?;
        Ok(())
    }
}
