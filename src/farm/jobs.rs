//! A job's side of the queue: its tasks queued, its end (cancelled, or failed by a task at
//! its failure limit) told to every worker through NOTIFY, its results read back in merge
//! order, and the queue's depth per user.

use sqlx::{Postgres, Row, Transaction};

use super::queue::{CANCEL_CHANNEL, NewTask, TASKS_CHANNEL};
use super::{FarmError, Queue, Unit, epoch_seconds};

impl Queue {
    /// Queue the tasks of job `job_id` (which must exist and have none yet), in merge
    /// order, and wake the workers. One transaction: all of them or none.
    pub async fn add_tasks(&self, job_id: i64, tasks: &[NewTask]) -> Result<(), FarmError> {
        let mut tx = self.pool().begin().await?;
        queue_tasks(&mut tx, job_id, tasks).await?;
        tx.commit().await?;
        Ok(())
    }

    /// Cancel job `id`: its queued and leased tasks are dropped and the workers holding
    /// them told at once (NOTIFY). False if the job had ended already.
    pub async fn cancel_job(&self, id: i64) -> Result<bool, FarmError> {
        self.end_job(id, "cancelled", None).await
    }

    /// Delete finished job `id` with its tasks, results and images; false if it is not
    /// finished (or not there).
    pub async fn delete_job(&self, id: i64) -> Result<bool, FarmError> {
        let deleted = sqlx::query(
            "DELETE FROM jobs WHERE id = $1 AND status IN ('done', 'failed', 'cancelled')",
        )
        .bind(id)
        .execute(self.pool())
        .await?;
        Ok(deleted.rows_affected() == 1)
    }

    /// Fail job `id` with `reason` (a task at its failure limit).
    pub async fn fail_job(&self, id: i64, reason: &str) -> Result<bool, FarmError> {
        self.end_job(id, "failed", Some(reason)).await
    }

    async fn end_job(&self, id: i64, status: &str, error: Option<&str>) -> Result<bool, FarmError> {
        let mut tx = self.pool().begin().await?;
        let ended = sqlx::query(
            "UPDATE jobs SET status = $2, error = $3, finished = $4
              WHERE id = $1 AND status IN ('queued', 'running')",
        )
        .bind(id)
        .bind(status)
        .bind(error)
        .bind(epoch_seconds())
        .execute(&mut *tx)
        .await?;
        if ended.rows_affected() == 0 {
            return Ok(false);
        }
        sqlx::query(
            "UPDATE tasks SET state = 'cancelled', worker = NULL, lease_until = NULL
              WHERE job_id = $1 AND state IN ('queued', 'leased')",
        )
        .bind(id)
        .execute(&mut *tx)
        .await?;
        notify(&mut tx, CANCEL_CHANNEL, id).await?;
        tx.commit().await?;
        Ok(true)
    }

    /// The queue's depth for /metrics: queued tasks, and the users they belong to (one row,
    /// however many users queue).
    pub async fn queue_depth(&self) -> Result<QueueDepth, FarmError> {
        let (tasks, users): (i64, i64) = sqlx::query_as(
            "SELECT count(*), count(DISTINCT user_id) FROM tasks WHERE state = 'queued'",
        )
        .fetch_one(self.pool())
        .await?;
        Ok(QueueDepth { tasks, users })
    }

    /// The tasks of job `id` done so far (their seqs, in merge order): what a preview
    /// while it runs is made of.
    pub async fn done_tasks(&self, id: i64) -> Result<Vec<i32>, FarmError> {
        Ok(sqlx::query_scalar(
            "SELECT seq FROM tasks WHERE job_id = $1 AND state = 'done' ORDER BY seq",
        )
        .bind(id)
        .fetch_all(self.pool())
        .await?)
    }

    /// The units and results of job `id`'s done tasks among `seqs`, in merge order.
    pub async fn done_results(
        &self,
        id: i64,
        seqs: &[i32],
    ) -> Result<Vec<(i32, Unit, Vec<u8>)>, FarmError> {
        let rows = sqlx::query(
            "SELECT seq, unit::text, result FROM tasks
              WHERE job_id = $1 AND seq = ANY($2) AND state = 'done' AND result IS NOT NULL
              ORDER BY seq",
        )
        .bind(id)
        .bind(seqs)
        .fetch_all(self.pool())
        .await?;
        rows.iter()
            .map(|r| {
                let unit = serde_json::from_str(r.try_get(1)?)?;
                Ok((r.try_get(0)?, unit, r.try_get(2)?))
            })
            .collect()
    }

    /// Job `id`'s tasks' units, results and stats in merge order (None for a task not done).
    pub async fn results(&self, id: i64) -> Result<Vec<TaskResult>, FarmError> {
        let rows = sqlx::query(
            "SELECT unit::text, result, stats_json FROM tasks WHERE job_id = $1 ORDER BY seq",
        )
        .bind(id)
        .fetch_all(self.pool())
        .await?;
        rows.iter()
            .map(|r| {
                Ok(TaskResult {
                    unit: serde_json::from_str(r.try_get(0)?)?,
                    result: r.try_get(1)?,
                    stats_json: r.try_get(2)?,
                })
            })
            .collect()
    }
}

/// Queued tasks, and how many users they belong to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueueDepth {
    pub tasks: i64,
    pub users: i64,
}

/// A task's unit, and its result and STATS.json once it is done.
pub struct TaskResult {
    pub unit: Unit,
    pub result: Option<Vec<u8>>,
    pub stats_json: Option<String>,
}

/// Queue job `job_id`'s tasks in merge order within `tx` and wake the workers when it
/// commits.
pub(super) async fn queue_tasks(
    tx: &mut Transaction<'_, Postgres>,
    job_id: i64,
    tasks: &[NewTask],
) -> Result<(), FarmError> {
    for (seq, t) in tasks.iter().enumerate() {
        sqlx::query(
            "INSERT INTO tasks (job_id, seq, user_id, job_created, unit, memory_bytes)
             SELECT id, $2, user_id, created, $3::jsonb, $4 FROM jobs WHERE id = $1",
        )
        .bind(job_id)
        .bind(seq as i32)
        .bind(serde_json::to_string(&t.unit)?)
        .bind(super::db_bytes(t.memory_bytes))
        .execute(&mut **tx)
        .await?;
    }
    let updated = sqlx::query("UPDATE jobs SET tasks_total = $2 WHERE id = $1")
        .bind(job_id)
        .bind(tasks.len() as i32)
        .execute(&mut **tx)
        .await?;
    if updated.rows_affected() != 1 {
        return Err(FarmError::NoSuchJob(job_id));
    }
    notify(tx, TASKS_CHANNEL, job_id).await
}

/// NOTIFY `channel` with `job_id`, delivered when `tx` commits (and not at all if it rolls
/// back).
pub(super) async fn notify(
    tx: &mut Transaction<'_, Postgres>,
    channel: &str,
    job_id: i64,
) -> Result<(), FarmError> {
    sqlx::query("SELECT pg_notify($1, $2)")
        .bind(channel)
        .bind(job_id.to_string())
        .execute(&mut **tx)
        .await?;
    Ok(())
}
