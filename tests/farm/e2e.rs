//! The farm as processes: one `photonbox serve --store postgres://... --no-render` and
//! `photonbox worker` processes against a real PostgreSQL, driven over HTTP like a user
//! would. The job's image is compared with `photonbox render` of the same spec on one box,
//! byte for byte.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use reqwest::blocking::Client;
use serde_json::{Value, json};

use crate::pg::cluster;

const BIN: &str = env!("CARGO_BIN_EXE_photonbox");

/// A 48-pass ppm job, small enough for a test.
fn ppm_params() -> Value {
    json!({"integrator": "ppm", "photons": 3000, "caustic_photons": 3000, "iterations": 48,
           "width": 40, "height": 30, "seed": 11})
}

/// The same job by `photonbox render` on one box: its EXR's bytes.
fn one_box_exr() -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("one.exr");
    let out = Command::new(BIN)
        .arg("render")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell_mirror_glass.json"
        ))
        .arg("-o")
        .arg(dir.path().join("one.png"))
        .arg("--exr")
        .arg(&exr)
        .args([
            "--integrator",
            "ppm",
            "--photons",
            "3000",
            "--caustic-photons",
            "3000",
        ])
        .args([
            "--iterations",
            "48",
            "--width",
            "40",
            "--height",
            "30",
            "--seed",
            "11",
        ])
        .args(["--threads", "1"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read(&exr).unwrap()
}

/// A farm process, killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Proc {
    fn signal(&self, sig: i32) {
        // SAFETY: signalling our own child process.
        unsafe {
            libc::kill(self.0.id() as i32, sig);
        }
    }
}

/// An API instance: its base URL and the admin token it printed (a fresh store).
struct Api {
    _proc: Proc,
    base: String,
}

fn start_api(store: &str) -> (Api, Option<String>) {
    let mut child = Command::new(BIN)
        .args([
            "serve",
            "--no-render",
            "--addr",
            "127.0.0.1:0",
            "--store",
            store,
        ])
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

fn start_worker(store: &str, id: &str, lease_seconds: f64) -> Proc {
    let child = Command::new(BIN)
        .args(["worker", "--threads", "1", "--store", store, "--id", id])
        .args(["--lease-seconds", &lease_seconds.to_string()])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    Proc(child)
}

fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

impl Api {
    fn submit(&self, token: &str, params: Value) -> i64 {
        let r = client()
            .post(format!("{}/api/jobs", self.base))
            .bearer_auth(token)
            .json(&json!({"scene_name": "cornell_mirror_glass", "params": params}))
            .send()
            .unwrap();
        assert_eq!(r.status().as_u16(), 202);
        r.json::<Value>().unwrap()["id"].as_i64().unwrap()
    }

    fn get(&self, token: &str, path: &str) -> (u16, Vec<u8>) {
        let r = client()
            .get(format!("{}{path}", self.base))
            .bearer_auth(token)
            .send()
            .unwrap();
        (r.status().as_u16(), r.bytes().unwrap().to_vec())
    }

    fn job(&self, token: &str, id: i64) -> Value {
        let (status, body) = self.get(token, &format!("/api/jobs/{id}"));
        assert_eq!(status, 200);
        serde_json::from_slice(&body).unwrap()
    }

    /// Poll the job until `done(job)`, at most `limit`.
    fn wait(&self, token: &str, id: i64, limit: Duration, done: impl Fn(&Value) -> bool) -> Value {
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

    fn wait_done(&self, token: &str, id: i64) -> Vec<u8> {
        let job = self.wait(token, id, Duration::from_secs(240), |j| {
            j["status"] != "queued" && j["status"] != "running"
        });
        assert_eq!(job["status"], "done", "{job}");
        let (status, exr) = self.get(token, &format!("/api/jobs/{id}/image.exr"));
        assert_eq!(status, 200);
        exr
    }

    fn metric(&self, name: &str) -> i64 {
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
fn store_query<T: Send + 'static>(
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

fn fresh_store() -> String {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(cluster().fresh_db())
}

/// Workers that did a job's tasks.
fn workers_of(url: &str, id: i64) -> i64 {
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

#[test]
fn a_job_spread_over_three_workers_is_the_bytes_of_one_box() {
    let store = fresh_store();
    let (api, admin) = start_api(&store);
    let admin = admin.expect("a fresh store's API prints the admin token");
    let _workers: Vec<Proc> = (0..3)
        .map(|i| start_worker(&store, &format!("w{i}"), 10.0))
        .collect();
    let id = api.submit(&admin, ppm_params());
    let farm = api.wait_done(&admin, id);
    let job = api.job(&admin, id);
    assert_eq!(job["stats"]["farm"]["tasks"], 8, "{job}");
    assert!(workers_of(&store, id) >= 2, "the tasks were not spread");
    assert!(
        farm == one_box_exr(),
        "the farm's EXR differs from one box's"
    );
}

#[test]
fn a_worker_killed_mid_task_loses_it_to_another_and_the_bytes_hold() {
    let store = fresh_store();
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    let victim = start_worker(&store, "victim", 1.0);
    let id = api.submit(&admin, ppm_params());
    // As soon as the victim holds a task, SIGKILL it.
    let url = store.clone();
    store_query(&url, async move |pool| {
        let t0 = Instant::now();
        while sqlx::query_scalar::<_, i64>(
            "SELECT count(*) FROM tasks WHERE worker = 'victim' AND state = 'leased'",
        )
        .fetch_one(pool)
        .await
        .unwrap()
            == 0
        {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the victim never claimed"
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    });
    victim.signal(libc::SIGKILL);
    drop(victim);
    let _others: Vec<Proc> = (0..2)
        .map(|i| start_worker(&store, &format!("w{i}"), 10.0))
        .collect();
    let farm = api.wait_done(&admin, id);
    assert!(api.metric("photonbox_farm_store_leases_expired_total") >= 1);
    assert!(farm == one_box_exr(), "after a lost worker the EXR differs");
}

#[test]
fn a_worker_cut_off_from_the_store_has_its_stale_result_refused() {
    let store = fresh_store();
    // The cut-off worker logs in as a role of its own, which the test bars and lets back.
    store_query(&store, async |pool| {
        sqlx::raw_sql("CREATE ROLE cut LOGIN SUPERUSER")
            .execute(pool)
            .await
            .unwrap();
    });
    let cut_url = store.replacen("postgres://photonbox@", "postgres://cut@", 1);
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    let _cut = start_worker(&cut_url, "cut", 1.0);
    let id = api.submit(&admin, ppm_params());
    store_query(&store, async move |pool| {
        let t0 = Instant::now();
        while sqlx::query_scalar::<_, i64>(
            "SELECT count(*) FROM tasks WHERE worker = 'cut' AND state = 'leased'",
        )
        .fetch_one(pool)
        .await
        .unwrap()
            == 0
        {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the worker never claimed"
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        // Cut it off: no new logins, its connections terminated.
        sqlx::raw_sql(
            "ALTER ROLE cut NOLOGIN;
             SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE usename = 'cut';",
        )
        .execute(pool)
        .await
        .unwrap();
    });
    // Another worker finishes the job, the cut-off worker's task included.
    let _other = start_worker(&store, "other", 10.0);
    let farm = api.wait_done(&admin, id);
    assert!(farm == one_box_exr());
    // Let it back: it hands its (stale) result in, and the fence refuses it.
    store_query(&store, async |pool| {
        sqlx::raw_sql("ALTER ROLE cut LOGIN")
            .execute(pool)
            .await
            .unwrap();
    });
    let t0 = Instant::now();
    while api.metric("photonbox_farm_store_fenced_results_refused_total") == 0 {
        assert!(
            t0.elapsed() < Duration::from_secs(90),
            "no stale result was refused"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(api.get(&admin, &format!("/api/jobs/{id}/image.exr")).1 == farm);
}

#[test]
fn a_cancel_reaches_the_worker_within_a_second() {
    let store = fresh_store();
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    let _w = start_worker(&store, "w", 30.0);
    // One long task: a ppm job that stops by time renders whole on one worker.
    let mut params = ppm_params();
    params["iterations"] = json!(100000);
    params["time_limit"] = json!(600);
    let id = api.submit(&admin, params);
    api.wait(&admin, id, Duration::from_secs(60), |j| {
        j["status"] == "running"
    });
    let r = client()
        .delete(format!("{}/api/jobs/{id}", api.base))
        .bearer_auth(&admin)
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    let t0 = Instant::now();
    // The worker has stopped when it is free to claim again: its registry row's
    // heartbeat then goes on from the idle loop, and a new job is claimed at once.
    let next = api.submit(
        &admin,
        json!({"integrator": "raytrace", "spp": 1,
                                         "width": 8, "height": 8}),
    );
    api.wait(&admin, next, Duration::from_secs(1), |j| {
        j["status"] != "queued"
    });
    assert!(
        t0.elapsed() < Duration::from_secs(1),
        "the cancel took {:?}",
        t0.elapsed()
    );
    assert_eq!(api.job(&admin, id)["status"], "cancelled");
}
