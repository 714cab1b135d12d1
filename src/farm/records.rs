//! Users and jobs in the farm's store: what the API instances write at submit and read
//! for their views, and what a worker reads to render a task and writes at a job's end.
//! Rows are the SQLite store's (`server::store::JobRow`), so both stores describe a job
//! alike.

use sqlx::Row;

use super::queue::NewTask;
use super::{FarmError, Queue, epoch_seconds};
use crate::server::auth::User;
use crate::server::store::{JobRow, Status};

/// What a worker needs to render a job's tasks.
#[derive(Clone, Debug)]
pub struct JobSource {
    pub params_json: String,
    pub scene_name: Option<String>,
    pub scene_json: Option<String>,
}

/// A job's images, merged.
pub struct JobImages {
    pub exr: Vec<u8>,
    pub png: Vec<u8>,
}

const JOB_COLUMNS: &str = "id, user_id, public, status, scene_name,
    COALESCE(octet_length(scene_json), 0)::BIGINT AS scene_bytes, params_json, memory_bytes,
    result_estimate, width, height, created, started, finished, error, stats_json,
    tasks_done, tasks_total,
    COALESCE((SELECT name FROM users WHERE users.id = jobs.user_id), '') AS owner";

/// A job's tasks: how many are done of how many.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TaskCount {
    pub done: u32,
    pub total: u32,
}

impl TaskCount {
    /// A farm job's progress: its tasks done over its tasks.
    pub fn progress(self) -> f64 {
        if self.total > 0 {
            self.done as f64 / self.total as f64
        } else {
            0.0
        }
    }
}

/// What one user may hold, checked by [`Queue::submit_job`] (the one-box server's
/// `max_queued_per_user` and `storage_bytes_per_user`).
#[derive(Clone, Copy, Debug)]
pub struct UserLimits {
    pub max_queued: i64,
    pub storage_bytes: u64,
}

/// The limit a submission would pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverLimit {
    /// The user's queued jobs are at the limit.
    Queued,
    /// The user's jobs take `used` bytes, and this one would not fit beside them.
    Storage { used: u64 },
}

/// Bytes a user's jobs take, as the one-box server counts them (`Jobs::storage_of`):
/// uploaded scenes, and each job's images, or their estimate until it has them.
/// (`octet_length` of a stored value reads its size, not the value.)
const STORAGE_OF: &str = "SELECT COALESCE(sum(COALESCE(octet_length(scene_json), 0)
        + CASE WHEN status IN ('queued', 'running') THEN result_estimate
               ELSE COALESCE(octet_length(result_exr), 0) + COALESCE(octet_length(result_png), 0)
          END), 0)::BIGINT
      FROM jobs WHERE user_id = $1";

/// A job as the API instances show it: its row, its tasks' progress and its owner's name.
#[derive(Clone, Debug)]
pub struct FarmJob {
    pub row: JobRow,
    pub tasks: TaskCount,
    pub owner: String,
}

fn job_row(r: &sqlx::postgres::PgRow) -> Result<FarmJob, sqlx::Error> {
    let side = |c: &str| -> Result<Option<u32>, sqlx::Error> {
        Ok(r.try_get::<Option<i32>, _>(c)?
            .and_then(|v| u32::try_from(v).ok()))
    };
    let status: String = r.try_get("status")?;
    let (done, total): (i32, i32) = (r.try_get("tasks_done")?, r.try_get("tasks_total")?);
    let row = JobRow {
        id: r.try_get("id")?,
        user_id: r.try_get("user_id")?,
        public: r.try_get("public")?,
        status: Status::parse(&status).unwrap_or(Status::Failed),
        scene_name: r.try_get("scene_name")?,
        scene_bytes: r.try_get::<i64, _>("scene_bytes")?.max(0) as u64,
        result_bytes: 0,
        result_estimate: r.try_get::<i64, _>("result_estimate")?.max(0) as u64,
        params_json: r.try_get("params_json")?,
        size: side("width")?.zip(side("height")?),
        memory_bytes: r.try_get::<i64, _>("memory_bytes")?.max(0) as u64,
        created: r.try_get("created")?,
        started: r.try_get("started")?,
        finished: r.try_get("finished")?,
        error: r.try_get("error")?,
        stats_json: r.try_get("stats_json")?,
    };
    let count = |n: i32| u32::try_from(n).unwrap_or(0);
    let tasks = TaskCount {
        done: count(done),
        total: count(total),
    };
    Ok(FarmJob {
        row,
        tasks,
        owner: r.try_get("owner")?,
    })
}

impl Queue {
    /// Add a user with the hash of its token.
    pub async fn add_user(
        &self,
        name: &str,
        token_hash: &str,
        admin: bool,
    ) -> Result<i64, FarmError> {
        let id: i64 = sqlx::query_scalar(
            "INSERT INTO users (id, name, token_hash, admin, created)
             VALUES ((SELECT COALESCE(max(id), 0) + 1 FROM users), $1, $2, $3, $4)
             RETURNING id",
        )
        .bind(name)
        .bind(token_hash)
        .bind(admin)
        .bind(epoch_seconds())
        .fetch_one(self.pool())
        .await?;
        Ok(id)
    }

    pub async fn user_by_token_hash(&self, hash: &str) -> Result<Option<User>, FarmError> {
        let row = sqlx::query("SELECT id, name, admin FROM users WHERE token_hash = $1")
            .bind(hash)
            .fetch_optional(self.pool())
            .await?;
        Ok(row
            .map(|r| -> Result<User, sqlx::Error> {
                Ok(User {
                    id: r.try_get(0)?,
                    name: r.try_get(1)?,
                    admin: r.try_get(2)?,
                })
            })
            .transpose()?)
    }

    /// Commit a new queued job and its tasks in one transaction (durable before the API
    /// acknowledges it), and wake the workers; or refuse it if it would pass one of its
    /// owner's `limits`. The limits are checked inside the transaction, under a lock on the
    /// owner's row: one submission per user at a time, whichever API instance takes it, so
    /// that no two pass a limit together. Returns its id: random in 1..2^53, as the SQLite
    /// store's.
    pub async fn submit_job(
        &self,
        row: &JobRow,
        scene_json: Option<&str>,
        tasks: &[NewTask],
        limits: UserLimits,
    ) -> Result<Result<i64, OverLimit>, FarmError> {
        let mut tx = self.pool().begin().await?;
        sqlx::query("SELECT 1 FROM users WHERE id = $1 FOR UPDATE")
            .bind(row.user_id)
            .execute(&mut *tx)
            .await?;
        let queued: i64 = sqlx::query_scalar(
            "SELECT count(*) FROM jobs WHERE user_id = $1 AND status = 'queued'",
        )
        .bind(row.user_id)
        .fetch_one(&mut *tx)
        .await?;
        if queued >= limits.max_queued {
            return Ok(Err(OverLimit::Queued));
        }
        let used: i64 = sqlx::query_scalar(STORAGE_OF)
            .bind(row.user_id)
            .fetch_one(&mut *tx)
            .await?;
        let used = used.max(0) as u64;
        if used + row.scene_bytes + row.result_estimate > limits.storage_bytes {
            return Ok(Err(OverLimit::Storage { used }));
        }
        let id = rand::random_range(1..(1i64 << 53));
        sqlx::query(
            "INSERT INTO jobs (id, user_id, public, status, scene_name, scene_json, params_json,
                               memory_bytes, result_estimate, width, height, created)
             VALUES ($1, $2, $3, 'queued', $4, $5, $6, $7, $8, $9, $10, $11)",
        )
        .bind(id)
        .bind(row.user_id)
        .bind(row.public)
        .bind(&row.scene_name)
        .bind(scene_json)
        .bind(&row.params_json)
        .bind(super::db_bytes(row.memory_bytes))
        .bind(super::db_bytes(row.result_estimate))
        .bind(row.size.map(|s| s.0 as i32))
        .bind(row.size.map(|s| s.1 as i32))
        .bind(row.created)
        .execute(&mut *tx)
        .await?;
        super::jobs::queue_tasks(&mut tx, id, tasks).await?;
        tx.commit().await?;
        Ok(Ok(id))
    }

    /// A job's row, its progress (tasks done over tasks) and its owner.
    pub async fn job(&self, id: i64) -> Result<Option<FarmJob>, FarmError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = $1");
        let row = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(self.pool())
            .await?;
        Ok(row.as_ref().map(job_row).transpose()?)
    }

    /// The jobs `user` may see (its own and public ones; an admin every one), newest first,
    /// at most `limit`.
    pub async fn visible_jobs(
        &self,
        user: i64,
        admin: bool,
        limit: i64,
    ) -> Result<Vec<FarmJob>, FarmError> {
        let sql = format!(
            "SELECT {JOB_COLUMNS} FROM jobs WHERE $2 OR user_id = $1 OR public
              ORDER BY created DESC, id DESC LIMIT $3"
        );
        let rows = sqlx::query(sqlx::AssertSqlSafe(sql))
            .bind(user)
            .bind(admin)
            .bind(limit)
            .fetch_all(self.pool())
            .await?;
        Ok(rows.iter().map(job_row).collect::<Result<_, _>>()?)
    }

    /// What a worker reads to render job `id`'s tasks.
    pub async fn job_source(&self, id: i64) -> Result<JobSource, FarmError> {
        let r = sqlx::query("SELECT params_json, scene_name, scene_json FROM jobs WHERE id = $1")
            .bind(id)
            .fetch_optional(self.pool())
            .await?
            .ok_or(FarmError::NoSuchJob(id))?;
        Ok(JobSource {
            params_json: r.try_get("params_json")?,
            scene_name: r.try_get("scene_name")?,
            scene_json: r.try_get("scene_json")?,
        })
    }

    /// End a running job with its images and stats (the worker that completed its last
    /// task), and drop its tasks' results in the same transaction: merged, they are of no
    /// further use, and a finished job keeps only its images (a ppm task's sums are 48
    /// bytes a pixel). False if the job had ended meanwhile (cancelled).
    pub async fn finish_job(
        &self,
        id: i64,
        images: &JobImages,
        stats_json: &str,
    ) -> Result<bool, FarmError> {
        let mut tx = self.pool().begin().await?;
        let done = sqlx::query(
            "UPDATE jobs SET status = 'done', finished = $2, result_exr = $3, result_png = $4,
                    stats_json = $5
              WHERE id = $1 AND status = 'running'",
        )
        .bind(id)
        .bind(epoch_seconds())
        .bind(&images.exr)
        .bind(&images.png)
        .bind(stats_json)
        .execute(&mut *tx)
        .await?;
        if done.rows_affected() != 1 {
            return Ok(false);
        }
        sqlx::query("UPDATE tasks SET result = NULL WHERE job_id = $1")
            .bind(id)
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// The length of a finished job's image (`exr` or `png`), if it has one.
    pub async fn job_image_len(&self, id: i64, exr: bool) -> Result<Option<u64>, FarmError> {
        let column = image_column(exr);
        let sql = format!("SELECT octet_length({column})::int8 FROM jobs WHERE id = $1");
        let len: Option<Option<i64>> = sqlx::query_scalar(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(self.pool())
            .await?;
        Ok(len.flatten().map(|n| n as u64))
    }

    /// Bytes `start..start + len` of a finished job's image: the images are stored
    /// uncompressed (migration 0004), so PostgreSQL reads only the slices' own chunks.
    /// (Offsets are `int4` in SQL: a `bytea` holds at most 1 GB.)
    pub async fn job_image_part(
        &self,
        id: i64,
        exr: bool,
        start: u64,
        len: u64,
    ) -> Result<Option<Vec<u8>>, FarmError> {
        let column = image_column(exr);
        let sql = format!("SELECT substring({column} FROM $2 FOR $3) FROM jobs WHERE id = $1");
        let bytes: Option<Option<Vec<u8>>> = sqlx::query_scalar(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .bind(start as i32 + 1)
            .bind(len as i32)
            .fetch_optional(self.pool())
            .await?;
        Ok(bytes.flatten())
    }

    /// A finished job's image (`exr` or `png`).
    pub async fn job_image(&self, id: i64, exr: bool) -> Result<Option<Vec<u8>>, FarmError> {
        let sql = format!("SELECT {} FROM jobs WHERE id = $1", image_column(exr));
        let bytes: Option<Option<Vec<u8>>> = sqlx::query_scalar(sqlx::AssertSqlSafe(sql))
            .bind(id)
            .fetch_optional(self.pool())
            .await?;
        Ok(bytes.flatten())
    }
}

/// The column of a job's finished image (a fixed name: safe to put in the SQL).
fn image_column(exr: bool) -> &'static str {
    if exr { "result_exr" } else { "result_png" }
}
