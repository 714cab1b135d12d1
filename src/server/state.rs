//! The live view of every job: its stored row plus what changes too fast to store (progress,
//! phase, ETA), published through a `watch` channel per job that SSE streams follow.
//! Every status change is written through to the store before it is published.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use serde::Serialize;
use tokio::sync::watch;

use super::auth::UserId;
use super::store::{JobRow, Status};

/// What an SSE client or a poll sees change.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Snapshot {
    #[serde(serialize_with = "status_str")]
    pub status: Status,
    /// 0..1, monotone while the job runs.
    pub progress: f64,
    pub phase: Option<&'static str>,
    pub eta_seconds: Option<f64>,
    /// How many images have been published (a final image counts).
    pub previews: u64,
    pub error: Option<String>,
}

fn status_str<S: serde::Serializer>(s: &Status, ser: S) -> Result<S::Ok, S::Error> {
    ser.serialize_str(s.as_str())
}

impl Snapshot {
    pub fn of(row: &JobRow) -> Snapshot {
        Snapshot {
            status: row.status,
            progress: if row.status == Status::Done { 1.0 } else { 0.0 },
            phase: None,
            eta_seconds: (row.status == Status::Done).then_some(0.0),
            previews: (row.status == Status::Done) as u64,
            error: row.error.clone(),
        }
    }
}

pub struct JobEntry {
    pub row: JobRow,
    pub live: Arc<watch::Sender<Snapshot>>,
}

/// All jobs, by id.
#[derive(Default)]
pub struct Jobs {
    map: Mutex<BTreeMap<i64, JobEntry>>,
}

impl Jobs {
    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<i64, JobEntry>> {
        self.map.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn insert(&self, row: JobRow) {
        let (tx, _) = watch::channel(Snapshot::of(&row));
        self.lock().insert(
            row.id,
            JobEntry {
                row,
                live: Arc::new(tx),
            },
        );
    }

    /// Bytes of storage a user's jobs take: uploaded scenes and result files.
    pub fn storage_of(&self, user: UserId) -> u64 {
        self.lock()
            .values()
            .filter(|e| e.row.user_id == user)
            .map(|e| e.row.scene_bytes + e.row.result_bytes)
            .sum()
    }

    pub fn remove(&self, id: i64) -> Option<JobRow> {
        self.lock().remove(&id).map(|e| e.row)
    }

    pub fn row(&self, id: i64) -> Option<JobRow> {
        self.lock().get(&id).map(|e| e.row.clone())
    }

    pub fn live(&self, id: i64) -> Option<Arc<watch::Sender<Snapshot>>> {
        self.lock().get(&id).map(|e| e.live.clone())
    }

    /// Row and current snapshot.
    pub fn view(&self, id: i64) -> Option<(JobRow, Snapshot)> {
        self.lock()
            .get(&id)
            .map(|e| (e.row.clone(), e.live.borrow().clone()))
    }

    /// Rows and snapshots passing `keep`, newest first (ids are random: by creation time).
    pub fn list(&self, keep: impl Fn(&JobRow) -> bool) -> Vec<(JobRow, Snapshot)> {
        let mut out: Vec<_> = self
            .lock()
            .values()
            .filter(|e| keep(&e.row))
            .map(|e| (e.row.clone(), e.live.borrow().clone()))
            .collect();
        out.sort_by(|(a, _), (b, _)| b.created.total_cmp(&a.created).then(b.id.cmp(&a.id)));
        out
    }

    /// Replace a job's row with one already committed to the store, and publish its status
    /// (see `App::commit_job`). False if the job is gone.
    pub fn publish(&self, row: JobRow) -> bool {
        let mut map = self.lock();
        let Some(e) = map.get_mut(&row.id) else {
            return false;
        };
        e.row = row;
        let row = &e.row;
        e.live.send_modify(|s| {
            s.status = row.status;
            s.error = row.error.clone();
            if row.status == Status::Done {
                s.progress = 1.0;
                s.eta_seconds = Some(0.0);
                s.previews += 1;
            }
            if row.status.is_final() || row.status == Status::Queued {
                s.phase = None;
            }
            if row.status == Status::Queued {
                s.progress = 0.0;
                s.eta_seconds = None;
            }
        });
        true
    }

    pub fn count_by_status(&self) -> BTreeMap<&'static str, u64> {
        let mut out: BTreeMap<&'static str, u64> =
            Status::ALL.iter().map(|s| (s.as_str(), 0)).collect();
        for e in self.lock().values() {
            *out.entry(e.row.status.as_str()).or_default() += 1;
        }
        out
    }

    pub fn queued_of(&self, user: UserId) -> usize {
        self.lock()
            .values()
            .filter(|e| e.row.user_id == user && e.row.status == Status::Queued)
            .count()
    }
}
