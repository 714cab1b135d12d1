//! The durable store: users and jobs in SQLite (WAL, synchronous=FULL: a job acknowledged
//! with 202 has been committed and survives SIGKILL or power loss). Result images are files
//! beside it (see `results::result_path`). The server keeps a live in-memory view of the jobs
//! and writes every state change through to here.

use std::path::Path;
use std::sync::Mutex;
use std::time::{SystemTime, UNIX_EPOCH};

use rusqlite::{Connection, OptionalExtension, params};

use super::auth::{User, UserId, new_token, token_hash};

/// A job's lifecycle.
#[derive(serde::Serialize, utoipa::ToSchema, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Queued,
    Running,
    Done,
    Failed,
    Cancelled,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Queued => "queued",
            Status::Running => "running",
            Status::Done => "done",
            Status::Failed => "failed",
            Status::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<Status> {
        Some(match s {
            "queued" => Status::Queued,
            "running" => Status::Running,
            "done" => Status::Done,
            "failed" => Status::Failed,
            "cancelled" => Status::Cancelled,
            _ => return None,
        })
    }

    pub fn is_final(self) -> bool {
        matches!(self, Status::Done | Status::Failed | Status::Cancelled)
    }

    pub const ALL: [Status; 5] = [
        Status::Queued,
        Status::Running,
        Status::Done,
        Status::Failed,
        Status::Cancelled,
    ];
}

/// A job as stored.
#[derive(Clone, Debug)]
pub struct JobRow {
    pub id: i64,
    pub user_id: UserId,
    pub public: bool,
    pub status: Status,
    /// A built-in scene's name, or the name given in an uploaded scene.
    pub scene_name: Option<String>,
    /// Bytes of the uploaded scene's JSON (0 for built-in scenes, which are read from
    /// scenes/). The text itself stays in the store (`Store::scene_json`): the live job table
    /// and every job listing would otherwise carry it.
    pub scene_bytes: u64,
    /// Bytes of the job's result files on disk (PNG, EXR, a progressive job's state), as
    /// last measured; with `scene_bytes`, what the job takes of its owner's storage quota
    /// (at least `result_estimate` until the job is final).
    pub result_bytes: u64,
    /// The estimated size of the result files (`needs::JobNeeds::result_bytes`), stored.
    pub result_estimate: u64,
    /// The job's spec as validated: every field its integrator reads (`JobSpec::to_form`;
    /// rows from before specs were stored whole hold the params as submitted).
    pub params_json: String,
    /// The output's width and height (resolved at submit): a reference must match them.
    pub size: Option<(u32, u32)>,
    /// Estimated peak memory of the render (`needs::JobNeeds`), kept so that a restart can
    /// queue the job without parsing its scene again.
    pub memory_bytes: u64,
    pub created: f64,
    pub started: Option<f64>,
    pub finished: Option<f64>,
    pub error: Option<String>,
    pub stats_json: Option<String>,
}

pub fn now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

pub struct Store {
    conn: Mutex<Connection>,
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS users (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE,
    token_hash TEXT NOT NULL UNIQUE,
    admin INTEGER NOT NULL,
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS jobs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    user_id INTEGER NOT NULL REFERENCES users(id),
    public INTEGER NOT NULL,
    status TEXT NOT NULL,
    scene_name TEXT,
    scene_json TEXT,
    params_json TEXT NOT NULL,
    memory_bytes INTEGER NOT NULL,
    created REAL NOT NULL,
    started REAL,
    finished REAL,
    error TEXT,
    stats_json TEXT
);
";

/// Columns added since the first schema, added to stores made before them.
fn migrate(conn: &Connection) -> rusqlite::Result<()> {
    let has = |col: &str| -> rusqlite::Result<bool> {
        let mut st = conn.prepare("SELECT 1 FROM pragma_table_info('jobs') WHERE name = ?1")?;
        st.exists([col])
    };
    if !has("result_estimate")? {
        // The estimated size of the job's result files (its storage until they exist).
        conn.execute_batch(
            "ALTER TABLE jobs ADD COLUMN result_estimate INTEGER NOT NULL DEFAULT 0",
        )?;
    }
    if !has("width")? {
        // The output size, resolved at submit; a finished job of an older store has it in
        // its stats.
        conn.execute_batch(
            "ALTER TABLE jobs ADD COLUMN width INTEGER;
             ALTER TABLE jobs ADD COLUMN height INTEGER;
             UPDATE jobs SET width = json_extract(stats_json, '$.params.width'),
                             height = json_extract(stats_json, '$.params.height')
              WHERE stats_json IS NOT NULL AND json_valid(stats_json);",
        )?;
    }
    Ok(())
}

/// An image side as stored (NULL, or anything but a u32 from an edited store: unknown).
fn side(v: rusqlite::types::ValueRef) -> Option<u32> {
    match v {
        rusqlite::types::ValueRef::Integer(i) => u32::try_from(i).ok(),
        _ => None,
    }
}

impl Store {
    pub fn open(dir: &Path) -> rusqlite::Result<Store> {
        let conn = Connection::open(dir.join("photonbox.sqlite3"))?;
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "FULL")?;
        conn.pragma_update(None, "foreign_keys", "ON")?;
        conn.busy_timeout(std::time::Duration::from_secs(5))?;
        conn.execute_batch(SCHEMA)?;
        migrate(&conn)?;
        Ok(Store {
            conn: Mutex::new(conn),
        })
    }

    fn conn(&self) -> std::sync::MutexGuard<'_, Connection> {
        self.conn.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn user_count(&self) -> rusqlite::Result<i64> {
        self.conn()
            .query_row("SELECT COUNT(*) FROM users", [], |r| r.get(0))
    }

    /// Add a user; returns it and its token (the only time the token exists in clear).
    pub fn add_user(&self, name: &str, admin: bool) -> rusqlite::Result<(User, String)> {
        let token = new_token();
        let conn = self.conn();
        conn.execute(
            "INSERT INTO users (name, token_hash, admin, created) VALUES (?1, ?2, ?3, ?4)",
            params![name, token_hash(&token), admin, now()],
        )?;
        let user = User {
            id: conn.last_insert_rowid(),
            name: name.to_string(),
            admin,
        };
        Ok((user, token))
    }

    /// Create the admin user again with a known token hash (a store that lost its users; see
    /// `server::ensure_admin`). Fails if a user named "admin" exists.
    pub fn restore_admin(&self, token_hash: &str) -> rusqlite::Result<()> {
        self.conn().execute(
            "INSERT INTO users (name, token_hash, admin, created) VALUES ('admin', ?1, 1, ?2)",
            params![token_hash, now()],
        )?;
        Ok(())
    }

    pub fn user_by_token_hash(&self, hash: &str) -> rusqlite::Result<Option<User>> {
        self.conn()
            .query_row(
                "SELECT id, name, admin FROM users WHERE token_hash = ?1",
                [hash],
                |r| {
                    Ok(User {
                        id: r.get(0)?,
                        name: r.get(1)?,
                        admin: r.get(2)?,
                    })
                },
            )
            .optional()
    }

    pub fn user_names(&self) -> rusqlite::Result<Vec<(UserId, String)>> {
        let conn = self.conn();
        let mut st = conn.prepare("SELECT id, name FROM users")?;
        let rows = st.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?;
        rows.collect()
    }

    /// Commit a new queued job with its uploaded scene (None: a built-in one); returns its
    /// id.
    ///
    /// Ids are random in 1..2^53 (exact in JavaScript's numbers), never a sequence: a store
    /// that lost rows (its WAL gone after a crash) forgets its sequence too, and would hand
    /// an old job's id, and so its result files, to a new job of another user.
    pub fn insert_job(&self, row: &JobRow, scene_json: Option<&str>) -> rusqlite::Result<i64> {
        let conn = self.conn();
        let mut tries = 0;
        loop {
            let id = rand::random_range(1..(1i64 << 53));
            let inserted = conn.execute(
                "INSERT INTO jobs (id, user_id, public, status, scene_name, scene_json,
                                   params_json, memory_bytes, created, result_estimate,
                                   width, height)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
                params![
                    id,
                    row.user_id,
                    row.public,
                    row.status.as_str(),
                    row.scene_name,
                    scene_json,
                    row.params_json,
                    row.memory_bytes as i64,
                    row.created,
                    row.result_estimate as i64,
                    row.size.map(|s| s.0),
                    row.size.map(|s| s.1)
                ],
            );
            match inserted {
                Ok(_) => return Ok(id),
                // An id taken already (about n / 2^53 a try): draw another.
                Err(rusqlite::Error::SqliteFailure(f, _))
                    if f.extended_code == rusqlite::ffi::SQLITE_CONSTRAINT_PRIMARYKEY
                        && tries < 8 =>
                {
                    tries += 1;
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// A job's uploaded scene, read when the job starts.
    pub fn scene_json(&self, id: i64) -> rusqlite::Result<Option<String>> {
        self.conn()
            .query_row("SELECT scene_json FROM jobs WHERE id = ?1", [id], |r| {
                r.get(0)
            })
            .optional()
            .map(Option::flatten)
    }

    /// Write a job's state (status, times, error, stats).
    pub fn update_job(&self, row: &JobRow) -> rusqlite::Result<()> {
        self.conn().execute(
            "UPDATE jobs SET status = ?2, started = ?3, finished = ?4, error = ?5, stats_json = ?6
             WHERE id = ?1",
            params![
                row.id,
                row.status.as_str(),
                row.started,
                row.finished,
                row.error,
                row.stats_json
            ],
        )?;
        Ok(())
    }

    pub fn delete_job(&self, id: i64) -> rusqlite::Result<()> {
        self.conn()
            .execute("DELETE FROM jobs WHERE id = ?1", [id])?;
        Ok(())
    }

    /// Every job, oldest first (by creation: ids are random).
    pub fn all_jobs(&self) -> rusqlite::Result<Vec<JobRow>> {
        let conn = self.conn();
        let mut st = conn.prepare(
            "SELECT id, user_id, public, status, scene_name, length(CAST(scene_json AS BLOB)),
                    params_json, created, started, finished, error, stats_json, memory_bytes,
                    result_estimate, width, height
             FROM jobs ORDER BY created, id",
        )?;
        let rows = st.query_map([], |r| {
            let status: String = r.get(3)?;
            Ok(JobRow {
                id: r.get(0)?,
                user_id: r.get(1)?,
                public: r.get(2)?,
                status: Status::parse(&status).unwrap_or(Status::Failed),
                scene_name: r.get(4)?,
                scene_bytes: r.get::<_, Option<i64>>(5)?.unwrap_or(0).max(0) as u64,
                result_bytes: 0,
                params_json: r.get(6)?,
                created: r.get(7)?,
                started: r.get(8)?,
                finished: r.get(9)?,
                error: r.get(10)?,
                stats_json: r.get(11)?,
                memory_bytes: r.get::<_, i64>(12)?.max(0) as u64,
                result_estimate: r.get::<_, i64>(13)?.max(0) as u64,
                size: side(r.get_ref(14)?).zip(side(r.get_ref(15)?)),
            })
        })?;
        rows.collect()
    }
}
