//! The workers' registry: each worker announces itself at start and with every heartbeat,
//! so that admins can list the farm (`GET /api/workers`) with each worker's last sign of
//! life, and a worker shutting down gracefully leaves.

use sqlx::Row;

use super::{FarmError, Queue};

/// The farm's workers (`GET /api/workers`).
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct WorkerList {
    pub workers: Vec<WorkerRow>,
}

/// A worker as the registry has it.
#[derive(serde::Serialize, utoipa::ToSchema, Clone, Debug, PartialEq)]
pub struct WorkerRow {
    pub id: String,
    pub threads: i32,
    pub memory_bytes: i64,
    /// Seconds since its last heartbeat, by the database's clock.
    pub seconds_since_heartbeat: f64,
    /// Tasks it completed (results accepted).
    pub tasks_done: i64,
}

impl Queue {
    /// Register worker `id` (or refresh its row after a restart).
    pub async fn register_worker(
        &self,
        id: &str,
        threads: u32,
        memory_bytes: u64,
    ) -> Result<(), FarmError> {
        sqlx::query(
            "INSERT INTO workers (id, threads, memory_bytes) VALUES ($1, $2, $3)
             ON CONFLICT (id) DO UPDATE SET threads = $2, memory_bytes = $3,
                    started = now(), last_heartbeat = now()",
        )
        .bind(id)
        .bind(threads as i32)
        .bind(super::db_bytes(memory_bytes))
        .execute(self.pool())
        .await?;
        Ok(())
    }

    /// Worker `id` is alive.
    pub async fn worker_alive(&self, id: &str) -> Result<(), FarmError> {
        sqlx::query("UPDATE workers SET last_heartbeat = now() WHERE id = $1")
            .bind(id)
            .execute(self.pool())
            .await?;
        Ok(())
    }

    /// Worker `id` is leaving.
    pub async fn deregister_worker(&self, id: &str) -> Result<(), FarmError> {
        sqlx::query("DELETE FROM workers WHERE id = $1")
            .bind(id)
            .execute(self.pool())
            .await?;
        Ok(())
    }

    /// Every registered worker, by id.
    pub async fn workers(&self) -> Result<Vec<WorkerRow>, FarmError> {
        let rows = sqlx::query(
            "SELECT id, threads, memory_bytes, tasks_done,
                    EXTRACT(EPOCH FROM now() - last_heartbeat)::float8 AS since
               FROM workers ORDER BY id",
        )
        .fetch_all(self.pool())
        .await?;
        rows.iter()
            .map(|r| {
                Ok(WorkerRow {
                    id: r.try_get("id")?,
                    threads: r.try_get("threads")?,
                    memory_bytes: r.try_get("memory_bytes")?,
                    seconds_since_heartbeat: r.try_get("since")?,
                    tasks_done: r.try_get("tasks_done")?,
                })
            })
            .collect()
    }
}
