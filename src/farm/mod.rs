//! The render farm's shared state in PostgreSQL (issue 21; design and failure model in
//! docs/farm.md): the schema and its migrations (`migrations/`, applied at start), the task
//! queue with leases and fenced results (`queue`), and the workers' registry (`workers`).
//!
//! The engine knows nothing of this module; the farm splits a job into units the engine
//! renders independently (a range of passes, or a tile) and merges their results in order.

use std::sync::atomic::{AtomicU64, Ordering};

pub mod api;
mod download;
mod events;
mod jobs;
pub mod outcome;
mod prepared;
pub mod preview;
pub mod probe;
pub mod queue;
mod records;
pub mod run;
mod snapshot;
pub mod task;
pub mod worker;
pub mod workers;

pub use jobs::{QueueDepth, TaskResult};
pub use queue::{Completion, Lease, LeaseLost, NewTask, Queue};
pub use records::{FarmJob, JobImages, JobSource, OverLimit, TaskCount, UserLimits};
pub use worker::{WorkerConfig, run_worker};

/// What one task renders.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Unit {
    /// Passes `first .. first + count` of a progressive job (1-based, as the engine counts).
    Passes { first: u32, count: u32 },
    /// Image rows `first .. first + count` of a one-shot job (photon, raytrace): a tile.
    Rows { first: u32, count: u32 },
    /// The whole job on one worker: a small one-shot render, or a progressive one that
    /// stops by time or error rather than a pass count (it cannot be split ahead of time).
    Whole,
}

#[derive(Debug, thiserror::Error)]
pub enum FarmError {
    #[error("database: {0}")]
    Db(#[from] sqlx::Error),
    #[error("schema migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    #[error("a task's unit: {0}")]
    Unit(#[from] serde_json::Error),
    #[error("no job {0}")]
    NoSuchJob(i64),
    #[error("lease lost: {0}")]
    Lost(#[from] LeaseLost),
}

impl FarmError {
    /// Whether the store was out of reach (down, restarting, the connection lost), as
    /// opposed to refusing the request: worth trying again.
    pub fn is_transient(&self) -> bool {
        let db = match self {
            FarmError::Db(e) => e,
            FarmError::Migrate(sqlx::migrate::MigrateError::Execute(e)) => e,
            _ => return false,
        };
        match db {
            sqlx::Error::Io(_)
            | sqlx::Error::PoolTimedOut
            | sqlx::Error::PoolClosed
            | sqlx::Error::Protocol(_)
            | sqlx::Error::WorkerCrashed => true,
            // Class 08: connection exception; class 57: operator intervention (the
            // server shutting down, starting up, or ending our session).
            sqlx::Error::Database(e) => e
                .code()
                .is_some_and(|c| c.starts_with("08") || c.starts_with("57")),
            _ => false,
        }
    }
}

/// This process's queue counters (its /metrics).
#[derive(Debug, Default)]
pub struct QueueMetrics {
    claimed: AtomicU64,
    leases_expired: AtomicU64,
    fenced_refused: AtomicU64,
}

impl QueueMetrics {
    fn count_claim(&self) {
        self.claimed.fetch_add(1, Ordering::Relaxed);
    }

    fn count_expired(&self, n: u64) {
        self.leases_expired.fetch_add(n, Ordering::Relaxed);
    }

    fn count_fenced(&self) {
        self.fenced_refused.fetch_add(1, Ordering::Relaxed);
    }

    /// Tasks this process claimed.
    pub fn claimed(&self) -> u64 {
        self.claimed.load(Ordering::Relaxed)
    }

    /// Expired leases this process reaped (their tasks queued again, or failed).
    pub fn leases_expired(&self) -> u64 {
        self.leases_expired.load(Ordering::Relaxed)
    }

    /// Results this process handed in that were refused: the lease had passed on.
    pub fn fenced_refused(&self) -> u64 {
        self.fenced_refused.load(Ordering::Relaxed)
    }
}

/// A byte count as the schema's BIGINT (beyond i64, which no machine has, as i64::MAX).
fn db_bytes(bytes: u64) -> i64 {
    i64::try_from(bytes).unwrap_or(i64::MAX)
}

/// Seconds since the epoch, as the jobs table keeps times.
pub fn epoch_seconds() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}
