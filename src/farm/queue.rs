//! The task queue in PostgreSQL: workers claim tasks with `SELECT ... FOR UPDATE SKIP
//! LOCKED` under a lease that heartbeats extend, and every claim raises the task's attempt
//! number, which fences its result: a result is taken only from the attempt that holds the
//! lease now, so a worker that lost its lease (it stalled, or was cut off, and another
//! worker took the task over) can never merge a stale result. The design follows the
//! classic lease-and-fencing-token pattern (Gray and Cheriton, "Leases", SOSP 1989); the
//! lease clock is the database's `now()`, one clock for the whole farm, so a worker's own
//! clock skew does not matter.
//!
//! Fair share at task grain: the claim serves the user whose last task was claimed
//! longest ago (round-robin over users with queued work), FIFO within a user, and only a
//! task whose memory fits the claiming worker's budget.

use std::sync::Arc;
use std::time::Duration;

use sqlx::postgres::{PgArguments, PgListener, PgPool, PgPoolOptions};
use sqlx::query::Query;
use sqlx::{Postgres, Row, Transaction};

use super::{FarmError, QueueMetrics, Unit, db_bytes, epoch_seconds};

/// Channels of LISTEN/NOTIFY: new tasks (payload: the job id) and cancelled or failed jobs
/// (payload: the job id).
pub const TASKS_CHANNEL: &str = "photonbox_tasks";
pub const CANCEL_CHANNEL: &str = "photonbox_cancel";

/// Attempts that may fail (a reported failure, or a lease that expired) before the task
/// fails its job.
pub const DEFAULT_MAX_FAILURES: i32 = 3;

/// One task of a job, to be queued.
#[derive(Clone, Debug)]
pub struct NewTask {
    pub unit: Unit,
    pub memory_bytes: u64,
}

/// A task a worker holds: render `unit` of job `job_id`, and hand the result back with
/// this `attempt` before the lease runs out (or heartbeat).
#[derive(Clone, Debug, PartialEq)]
pub struct Lease {
    pub job_id: i64,
    pub seq: i32,
    pub attempt: i32,
    pub user_id: i64,
    pub unit: Unit,
}

enum Claim {
    Got(Lease),
    Nothing,
    /// The user picked had no task left that a simultaneous claim was not taking.
    Raced,
}

/// Why a lease is no longer the worker's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LeaseLost {
    #[error("the job was cancelled or has failed")]
    Cancelled,
    #[error("the lease expired and the task was handed to another attempt")]
    Superseded,
}

/// What became of a result handed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Completion {
    /// Stored; `job_done` when it was the job's last task (exactly one completion says so).
    Accepted { job_done: bool },
    /// Refused: the lease was no longer this attempt's (counted in the metrics).
    Refused(LeaseLost),
}

/// The queue: a connection pool and this process's counters.
#[derive(Clone)]
pub struct Queue {
    pool: PgPool,
    metrics: Arc<QueueMetrics>,
    max_failures: i32,
}

impl Queue {
    /// Connect with a pool of up to `connections` and apply the schema's migrations (the
    /// migrator takes an advisory lock, so instances starting together apply each once).
    pub async fn connect(url: &str, connections: u32) -> Result<Queue, FarmError> {
        let pool = PgPoolOptions::new()
            .max_connections(connections.max(1))
            .acquire_timeout(Duration::from_secs(30))
            .connect(url)
            .await?;
        sqlx::migrate!("src/farm/migrations").run(&pool).await?;
        Ok(Queue {
            pool,
            metrics: Arc::new(QueueMetrics::default()),
            max_failures: DEFAULT_MAX_FAILURES,
        })
    }

    /// The same queue with another failure limit (at least 1).
    pub fn with_max_failures(mut self, n: i32) -> Queue {
        self.max_failures = n.max(1);
        self
    }

    pub fn pool(&self) -> &PgPool {
        &self.pool
    }

    pub fn metrics(&self) -> &QueueMetrics {
        &self.metrics
    }

    /// A listener on both channels, for a worker's or an API instance's wake-ups.
    pub async fn listener(&self) -> Result<PgListener, FarmError> {
        let mut l = PgListener::connect_with(&self.pool).await?;
        l.listen_all([TASKS_CHANNEL, CANCEL_CHANNEL]).await?;
        Ok(l)
    }

    /// Claim the next task for worker `worker`, whose free memory is `memory_budget`
    /// bytes, under a lease of `lease` (None: nothing claimable fits). Expired leases are
    /// reaped first, so their tasks are claimable again.
    pub async fn claim(
        &self,
        worker: &str,
        memory_budget: u64,
        lease: Duration,
    ) -> Result<Option<Lease>, FarmError> {
        self.reap_expired().await?;
        let budget = db_bytes(memory_budget);
        // A claim that lost every task of its user to simultaneous claims looks again.
        for _ in 0..4 {
            match self.claim_once(worker, budget, lease).await? {
                Claim::Got(l) => {
                    self.metrics.count_claim();
                    return Ok(Some(l));
                }
                Claim::Nothing => return Ok(None),
                Claim::Raced => {}
            }
        }
        Ok(None)
    }

    async fn claim_once(
        &self,
        worker: &str,
        budget: i64,
        lease: Duration,
    ) -> Result<Claim, FarmError> {
        let mut tx = self.pool.begin().await?;
        let Some((user, locked)) = next_user(&mut tx, budget).await? else {
            return Ok(Claim::Nothing);
        };
        let row = sqlx::query(
            "UPDATE tasks t
                SET state = 'leased', attempt = t.attempt + 1, worker = $3,
                    lease_until = now() + make_interval(secs => $4)
              WHERE (t.job_id, t.seq) = (
                    SELECT job_id, seq FROM tasks
                     WHERE user_id = $1 AND state = 'queued' AND memory_bytes <= $2
                     ORDER BY job_created, job_id, seq
                     LIMIT 1
                     FOR UPDATE SKIP LOCKED)
             RETURNING t.job_id, t.seq, t.attempt, t.user_id, t.unit::text AS unit",
        )
        .bind(user)
        .bind(budget)
        .bind(worker)
        .bind(lease.as_secs_f64())
        .fetch_optional(&mut *tx)
        .await?;
        let Some(row) = row else {
            // Every fitting task of that user is being claimed right now.
            return Ok(Claim::Raced);
        };
        let claimed = Lease {
            job_id: row.try_get("job_id")?,
            seq: row.try_get("seq")?,
            attempt: row.try_get("attempt")?,
            user_id: row.try_get("user_id")?,
            unit: serde_json::from_str(row.try_get("unit")?)?,
        };
        if locked {
            sqlx::query("UPDATE users SET last_served = nextval('serve_clock') WHERE id = $1")
                .bind(claimed.user_id)
                .execute(&mut *tx)
                .await?;
        }
        sqlx::query(
            "UPDATE jobs SET status = 'running', started = COALESCE(started, $2)
              WHERE id = $1 AND status = 'queued'",
        )
        .bind(claimed.job_id)
        .bind(epoch_seconds())
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(Claim::Got(claimed))
    }

    /// Extend the lease by `lease` from now, if it is still this attempt's.
    pub async fn heartbeat(&self, l: &Lease, lease: Duration) -> Result<(), FarmError> {
        let done = for_lease(
            "UPDATE tasks SET lease_until = now() + make_interval(secs => $4)
              WHERE job_id = $1 AND seq = $2 AND attempt = $3 AND state = 'leased'",
            l,
        )
        .bind(lease.as_secs_f64())
        .execute(&self.pool)
        .await?;
        if done.rows_affected() == 1 {
            return Ok(());
        }
        Err(FarmError::Lost(self.why_lost(l).await?))
    }

    /// Hand in the result of a leased task (and its STATS.json). Stored with the task's
    /// completion in one transaction, and only if the lease is still this attempt's.
    pub async fn complete(
        &self,
        l: &Lease,
        result: &[u8],
        stats_json: Option<&str>,
    ) -> Result<Completion, FarmError> {
        let mut tx = self.pool.begin().await?;
        // The task's result and its worker's count, in one statement.
        let stored: i64 = for_lease(
            "WITH t AS (UPDATE tasks SET state = 'done', result = $4, stats_json = $5,
                               lease_until = NULL
                         WHERE job_id = $1 AND seq = $2 AND attempt = $3 AND state = 'leased'
                        RETURNING worker),
                  w AS (UPDATE workers SET tasks_done = tasks_done + 1
                         WHERE id IN (SELECT worker FROM t))
             SELECT count(*) FROM t",
            l,
        )
        .bind(result)
        .bind(stats_json)
        .fetch_one(&mut *tx)
        .await?
        .try_get(0)?;
        if stored != 1 {
            drop(tx);
            self.metrics.count_fenced();
            self.count_in_store("fenced_refused", 1).await?;
            return Ok(Completion::Refused(self.why_lost(l).await?));
        }
        let row = sqlx::query(
            "UPDATE jobs SET tasks_done = tasks_done + 1 WHERE id = $1
             RETURNING tasks_done, tasks_total",
        )
        .bind(l.job_id)
        .fetch_one(&mut *tx)
        .await?;
        let (done, total): (i32, i32) = (row.try_get(0)?, row.try_get(1)?);
        tx.commit().await?;
        Ok(Completion::Accepted {
            job_done: done == total,
        })
    }

    /// Report that this attempt failed: the task is queued again, or, at the failure
    /// limit, fails its job with `reason`. A lease no longer held is not counted.
    pub async fn fail(&self, l: &Lease, reason: &str) -> Result<(), FarmError> {
        let row = for_lease(
            "UPDATE tasks SET failures = failures + 1, error = $4, worker = NULL,
                    lease_until = NULL,
                    state = CASE WHEN failures + 1 >= $5 THEN 'failed' ELSE 'queued' END
              WHERE job_id = $1 AND seq = $2 AND attempt = $3 AND state = 'leased'
             RETURNING state",
            l,
        )
        .bind(reason)
        .bind(self.max_failures)
        .fetch_optional(&self.pool)
        .await?;
        let state: Option<String> = row.map(|r| r.try_get(0)).transpose()?;
        if state.as_deref() == Some("failed") {
            self.fail_job(l.job_id, &self.failed_reason(l.seq, reason))
                .await?;
        }
        Ok(())
    }

    /// Give the task back without counting a failure (a worker shutting down): queued
    /// again, and this attempt's result fenced off.
    pub async fn release(&self, l: &Lease) -> Result<(), FarmError> {
        for_lease(
            "UPDATE tasks SET state = 'queued', worker = NULL, lease_until = NULL
              WHERE job_id = $1 AND seq = $2 AND attempt = $3 AND state = 'leased'",
            l,
        )
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Queue again every task whose lease has expired (counting it as a failed attempt;
    /// at the limit its job fails). Returns how many were reaped.
    pub async fn reap_expired(&self) -> Result<u64, FarmError> {
        let rows = sqlx::query(
            "UPDATE tasks SET failures = failures + 1, worker = NULL, lease_until = NULL,
                    error = 'the lease expired (the worker stopped or lost the database)',
                    state = CASE WHEN failures + 1 >= $1 THEN 'failed' ELSE 'queued' END
              WHERE state = 'leased' AND lease_until <= now()
             RETURNING job_id, seq, state",
        )
        .bind(self.max_failures)
        .fetch_all(&self.pool)
        .await?;
        self.metrics.count_expired(rows.len() as u64);
        if !rows.is_empty() {
            self.count_in_store("leases_expired", rows.len() as i64)
                .await?;
        }
        for r in &rows {
            if r.try_get::<String, _>("state")? == "failed" {
                let reason = "its lease expired on every attempt";
                let why = self.failed_reason(r.try_get("seq")?, reason);
                self.fail_job(r.try_get("job_id")?, &why).await?;
            }
        }
        Ok(rows.len() as u64)
    }

    /// Add `n` to a farm-wide counter (`counters`).
    async fn count_in_store(&self, name: &str, n: i64) -> Result<(), FarmError> {
        sqlx::query("UPDATE counters SET n = n + $2 WHERE name = $1")
            .bind(name)
            .bind(n)
            .execute(&self.pool)
            .await?;
        Ok(())
    }

    fn failed_reason(&self, seq: i32, reason: &str) -> String {
        format!(
            "task {seq} failed {} times; last: {reason}",
            self.max_failures
        )
    }

    /// Why `l` is not the task's current lease (it was, when the caller last looked).
    async fn why_lost(&self, l: &Lease) -> Result<LeaseLost, FarmError> {
        let state: Option<String> =
            sqlx::query_scalar("SELECT state FROM tasks WHERE job_id = $1 AND seq = $2")
                .bind(l.job_id)
                .bind(l.seq)
                .fetch_optional(&self.pool)
                .await?;
        Ok(match state.as_deref() {
            Some("queued" | "leased" | "done") => LeaseLost::Superseded,
            _ => LeaseLost::Cancelled,
        })
    }
}

/// `sql` with the lease's job, task and attempt bound to $1, $2 and $3 (every statement
/// that acts on a lease names it by all three: the attempt is the fence).
fn for_lease<'q>(sql: &'static str, l: &Lease) -> Query<'q, Postgres, PgArguments> {
    sqlx::query(sql).bind(l.job_id).bind(l.seq).bind(l.attempt)
}

/// The user to serve next, and whether `tx` holds its row's lock: of the users with a
/// queued task that fits `budget`, the one served longest ago that no concurrent claim is
/// serving (SKIP LOCKED spreads simultaneous claims over the users, so round-robin holds
/// under concurrency too). When every such user is being served, the oldest one, unlocked:
/// its task is taken with the task's own SKIP LOCKED, and the claim serving that user stamps
/// its turn. Claims never wait for one another.
async fn next_user(
    tx: &mut Transaction<'_, Postgres>,
    budget: i64,
) -> Result<Option<(i64, bool)>, FarmError> {
    macro_rules! pick {
        ($lock:literal) => {
            concat!(
                "SELECT u.id FROM users u
                  WHERE EXISTS (SELECT 1 FROM tasks t
                                 WHERE t.user_id = u.id AND t.state = 'queued'
                                   AND t.memory_bytes <= $1)
                  ORDER BY u.last_served, u.id
                  LIMIT 1 ",
                $lock
            )
        };
    }
    for (sql, locked) in [(pick!("FOR UPDATE SKIP LOCKED"), true), (pick!(""), false)] {
        let user: Option<i64> = sqlx::query_scalar(sql)
            .bind(budget)
            .fetch_optional(&mut **tx)
            .await?;
        if let Some(user) = user {
            return Ok(Some((user, locked)));
        }
    }
    Ok(None)
}
