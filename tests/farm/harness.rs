//! The farm's processes for the end-to-end tests: an API instance, workers, and the same
//! deployment on one box with the embedded SQLite store (`Deployment`), so that the tests
//! that apply to both run on both.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use reqwest::blocking::Client;
use serde_json::{Value, json};

use crate::pg::{Cluster, cluster};

pub const BIN: &str = env!("CARGO_BIN_EXE_photonbox");

/// A 48-pass ppm job, small enough for a test.
pub fn ppm_params() -> Value {
    json!({"integrator": "ppm", "photons": 3000, "caustic_photons": 3000, "iterations": 48,
           "width": 40, "height": 30, "seed": 11})
}

/// A ppm job whose tasks (one pass each) take a few tenths of a second on one thread: long
/// enough that a worker seen holding one is still rendering it when a test kills it or
/// cuts it off (`ppm_params`' tasks take milliseconds).
pub fn slow_ppm_params() -> Value {
    json!({"integrator": "ppm", "photons": 300000, "caustic_photons": 300000,
           "iterations": 16, "width": 64, "height": 48, "seed": 5})
}

/// A photon-mapping job large enough to be split into bands of rows.
pub fn photon_params() -> Value {
    json!({"integrator": "photon", "photons": 20000, "caustic_photons": 20000,
           "width": 64, "height": 48, "spp": 2, "seed": 3})
}

/// The `ppm_params()` job by `photonbox render` on one box: its EXR's bytes (rendered
/// once per test run).
pub fn one_box_exr() -> Vec<u8> {
    static EXR: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    EXR.get_or_init(|| render_one_box(&ppm_params())).clone()
}

/// The `slow_ppm_params()` job by `photonbox render` on one box (once per test run).
pub fn slow_one_box_exr() -> Vec<u8> {
    static EXR: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    EXR.get_or_init(|| render_one_box(&slow_ppm_params()))
        .clone()
}

/// The job of `params` by `photonbox render` on one box (tests/common).
pub use crate::common::render_exr_by_cli as render_one_box;

/// A farm process, killed when dropped.
pub struct Proc(pub Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Proc {
    pub fn signal(&self, sig: i32) {
        // SAFETY: signalling our own child process.
        unsafe {
            libc::kill(self.0.id() as i32, sig);
        }
    }
}

/// An API instance: its base URL and the admin token it printed (a fresh store).
pub struct Api {
    _proc: Proc,
    pub base: String,
}

pub fn start_api(store: &str) -> (Api, Option<String>) {
    start_serve(&["--no-render", "--store", store])
}

/// `photonbox serve --addr 127.0.0.1:0` with `flags`: the API and the admin token it
/// printed, if it printed one.
fn start_serve(flags: &[&str]) -> (Api, Option<String>) {
    let mut child = Command::new(BIN)
        .args(["serve", "--addr", "127.0.0.1:0"])
        .args(flags)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut admin = None;
    let base = loop {
        let line = lines.next().expect("the API's output").unwrap();
        if let Some(t) = line.strip_prefix("photonbox: admin token (shown once): ") {
            admin = Some(t.to_string());
        }
        if let Some(rest) = line.strip_prefix("photonbox: listening on ") {
            break rest.split(' ').next().unwrap().to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (
        Api {
            _proc: Proc(child),
            base,
        },
        admin,
    )
}

pub fn start_worker(store: &str, id: &str, lease_seconds: f64) -> Proc {
    let child = Command::new(BIN)
        .args(["worker", "--threads", "1", "--store", store, "--id", id])
        .args(["--lease-seconds", &lease_seconds.to_string()])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    Proc(child)
}

/// `start_worker` answering its probes on a free port: the worker and the probes' base URL.
pub fn start_worker_with_probes(store: &str, id: &str) -> (Proc, String) {
    let mut child = Command::new(BIN)
        .args(["worker", "--threads", "1", "--store", store, "--id", id])
        .args(["--addr", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let base = loop {
        let line = lines.next().expect("the worker's output").unwrap();
        if let Some(rest) = line.strip_prefix("photonbox: worker probes on ") {
            break rest.to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (Proc(child), base)
}

pub fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

impl Api {
    pub fn submit(&self, token: &str, params: Value) -> i64 {
        let body = json!({"scene_name": "cornell_mirror_glass", "params": params});
        let (status, v) = self.post_job(token, &body);
        assert_eq!(status, 202, "{v}");
        v["id"].as_i64().unwrap()
    }

    /// `POST /api/jobs` with `body`: the status and the JSON answer.
    pub fn post_job(&self, token: &str, body: &Value) -> (u16, Value) {
        let r = client()
            .post(format!("{}/api/jobs", self.base))
            .bearer_auth(token)
            .json(body)
            .send()
            .unwrap();
        (r.status().as_u16(), r.json::<Value>().unwrap())
    }

    pub fn get(&self, token: &str, path: &str) -> (u16, Vec<u8>) {
        let r = client()
            .get(format!("{}{path}", self.base))
            .bearer_auth(token)
            .send()
            .unwrap();
        (r.status().as_u16(), r.bytes().unwrap().to_vec())
    }

    /// `DELETE /api/jobs/{id}` (cancel, or delete a finished job): the status.
    pub fn delete_job(&self, token: &str, id: i64) -> u16 {
        client()
            .delete(format!("{}/api/jobs/{id}", self.base))
            .bearer_auth(token)
            .send()
            .unwrap()
            .status()
            .as_u16()
    }

    pub fn job(&self, token: &str, id: i64) -> Value {
        let (status, body) = self.get(token, &format!("/api/jobs/{id}"));
        assert_eq!(status, 200);
        serde_json::from_slice(&body).unwrap()
    }

    /// Poll the job until `done(job)`, at most `limit`.
    pub fn wait(
        &self,
        token: &str,
        id: i64,
        limit: Duration,
        done: impl Fn(&Value) -> bool,
    ) -> Value {
        let t0 = Instant::now();
        loop {
            let job = self.job(token, id);
            if done(&job) {
                return job;
            }
            assert!(t0.elapsed() < limit, "job {id} after {limit:?}: {job}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    pub fn wait_done(&self, token: &str, id: i64) -> Vec<u8> {
        let job = self.wait(token, id, Duration::from_secs(240), |j| {
            j["status"] != "queued" && j["status"] != "running"
        });
        assert_eq!(job["status"], "done", "{job}");
        let (status, exr) = self.get(token, &format!("/api/jobs/{id}/image.exr"));
        assert_eq!(status, 200);
        exr
    }

    pub fn metric(&self, name: &str) -> i64 {
        let (_, text) = self.get("", "/metrics");
        let text = String::from_utf8(text).unwrap();
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("{name} ")))
            .unwrap_or_else(|| panic!("{name} not in /metrics:\n{text}"))
            .parse()
            .unwrap()
    }
}

/// A query on the store, from the test.
pub fn store_query<T: Send + 'static>(
    url: &str,
    f: impl AsyncFnOnce(&sqlx::PgPool) -> T + Send + 'static,
) -> T {
    let url = url.to_string();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async move {
        let pool = sqlx::PgPool::connect(&url).await.unwrap();
        let out = f(&pool).await;
        pool.close().await;
        out
    })
}

pub fn fresh_store() -> String {
    fresh_store_of(cluster())
}

pub fn fresh_store_of(c: &Cluster) -> String {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(c.fresh_db())
}

/// Workers that did a job's tasks.
pub fn workers_of(url: &str, id: i64) -> i64 {
    store_query(url, async move |pool| {
        sqlx::query_scalar::<_, i64>(
            "SELECT count(DISTINCT worker) FROM tasks WHERE job_id = $1 AND state = 'done'",
        )
        .bind(id)
        .fetch_one(pool)
        .await
        .unwrap()
    })
}

/// Which store a deployment runs on.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    /// PostgreSQL (a cluster of the deployment's own, so that it can restart it), an API
    /// instance with `--no-render`, and workers.
    Postgres,
    /// One box: `photonbox serve` on the embedded SQLite store, rendering itself.
    Sqlite,
}

/// A running deployment: its API, the admin's token and its render processes.
pub struct Deployment {
    pub api: Api,
    pub admin: String,
    kind: Kind,
    store: String,
    /// More flags for `serve`.
    flags: Vec<String>,
    cluster: Option<Cluster>,
    data: Option<tempfile::TempDir>,
    _workers: Vec<Proc>,
}

impl Deployment {
    /// Start a deployment of `kind` with `workers` workers (a farm; one box renders itself).
    pub fn start(kind: Kind, workers: usize) -> Deployment {
        Deployment::start_with(kind, workers, &[])
    }

    /// [`Deployment::start`] with more flags for `serve` (limits).
    pub fn start_with(kind: Kind, workers: usize, flags: &[&str]) -> Deployment {
        let (cluster, data, store) = match kind {
            Kind::Postgres => {
                let own = Cluster::new(true);
                let url = fresh_store_of(&own);
                (Some(own), None, url)
            }
            Kind::Sqlite => {
                let dir = tempfile::tempdir().unwrap();
                let path = dir.path().join("data").display().to_string();
                (None, Some(dir), path)
            }
        };
        let mut d = Deployment {
            api: Api::none(),
            admin: String::new(),
            kind,
            store,
            flags: flags.iter().map(|f| f.to_string()).collect(),
            cluster,
            data,
            _workers: Vec::new(),
        };
        d.start_api();
        d._workers = (0..workers)
            .filter(|_| matches!(kind, Kind::Postgres))
            .enumerate()
            .map(|(i, _)| start_worker(&d.store, &format!("w{i}"), 10.0))
            .collect();
        d
    }

    fn start_api(&mut self) {
        let base: Vec<&str> = match self.kind {
            Kind::Postgres => vec!["--no-render", "--store", &self.store],
            Kind::Sqlite => vec!["--threads", "1", "--data", &self.store],
        };
        let flags: Vec<&str> = self.flags.iter().map(String::as_str).collect();
        let (api, admin) = start_serve(&[base, flags].concat());
        self.api = api;
        let data_admin = self.data.as_ref().map(|_| {
            let path = std::path::Path::new(&self.store).join("admin-token");
            std::fs::read_to_string(path).unwrap().trim().to_string()
        });
        if let Some(token) = admin.or(data_admin) {
            self.admin = token;
        }
    }

    /// SIGKILL the API (on one box: the whole server), restart the store's server if it
    /// has one, and start the API again.
    pub fn crash_and_restart(&mut self) {
        self.api = Api::none();
        if let Some(c) = &self.cluster {
            c.stop();
            c.start();
        }
        self.start_api();
    }

    /// The store's URL (PostgreSQL) or data folder (SQLite).
    pub fn store(&self) -> &str {
        &self.store
    }

    /// `photonbox user add NAME` on the deployment's store: the new user's token.
    pub fn add_user(&self, name: &str) -> String {
        let flag = match self.kind {
            Kind::Postgres => "--store",
            Kind::Sqlite => "--data",
        };
        let out = Command::new(BIN)
            .args(["user", "add", name, flag, &self.store])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    }
}

impl Api {
    /// No API (the old one killed, before the next starts).
    fn none() -> Api {
        Api {
            _proc: Proc(Command::new("true").spawn().unwrap()),
            base: String::new(),
        }
    }
}

/// A test that applies to both stores, run on each: `both!(name)` runs `name(Kind)` as
/// `name::postgres` and `name::sqlite`.
#[macro_export]
macro_rules! both {
    ($name:ident) => {
        mod $name {
            use $crate::harness::Kind;
            #[test]
            fn postgres() {
                super::$name(Kind::Postgres)
            }
            #[test]
            fn sqlite() {
                super::$name(Kind::Sqlite)
            }
        }
    };
}

/// Wait (at most a minute) until worker `worker` holds a leased task.
pub async fn await_lease(pool: &sqlx::PgPool, worker: &str) {
    let t0 = Instant::now();
    loop {
        let held: i64 =
            sqlx::query_scalar("SELECT count(*) FROM tasks WHERE worker = $1 AND state = 'leased'")
                .bind(worker)
                .fetch_one(pool)
                .await
                .unwrap();
        if held > 0 {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "{worker} never claimed a task"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}
