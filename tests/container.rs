//! The Docker image and the compose farm (issue 21, item 3), on this machine's Docker engine.
//! No registry is reachable here: tests/docker/base-images.sh builds the base images from
//! Debian's packages first, and the Dockerfile is built with them as its build arguments
//! (and `PROFILE=quick`: the same program without release's fat LTO, which would take most
//! of CI's time).
//!
//! - one box: healthy by the image's own HEALTHCHECK, running as its non-root user, a job
//!   rendered (the same EXR bytes as `photonbox render`), and the data volume keeping the
//!   admin's token, the job and its image when the container is replaced;
//! - examples/compose.yaml brought up as a user would (PostgreSQL, one API, two workers): a
//!   48-pass ppm job spread over both workers, the EXR the CLI's bytes.

mod common;

use std::process::Command;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use reqwest::blocking::Client;
use serde_json::{Value, json};

use common::render_exr_by_cli;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const IMAGE: &str = "photonbox:container-test";
const BUILD_ARGS: [(&str, &str); 3] = [
    ("BUILD_IMAGE", "photonbox/rust:bookworm"),
    ("RUNTIME_IMAGE", "photonbox/debian:bookworm"),
    ("PROFILE", "quick"),
];

/// Run `cmd` to success; its standard output, trimmed.
fn run(cmd: &mut Command) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{cmd:?}: {e} (is Docker installed and its engine running?)"));
    assert!(
        out.status.success(),
        "{cmd:?}: {}\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

fn docker(args: &[&str]) -> String {
    run(Command::new("docker").args(args))
}

/// The Dockerfile's image as tests/docker/build-image.sh builds it (`IMAGE`, with
/// `BUILD_ARGS`), once per test run.
fn image() -> &'static str {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let script = format!("{ROOT}/tests/docker/build-image.sh");
        run(&mut Command::new(script));
    });
    IMAGE
}

/// Removes what a test made, however it ends.
struct Cleanup(Vec<Vec<String>>);

impl Drop for Cleanup {
    fn drop(&mut self) {
        for cmd in self.0.iter().rev() {
            let _ = Command::new(&cmd[0]).args(&cmd[1..]).output();
        }
    }
}

/// Wait until every container in `ids` is healthy by its HEALTHCHECK.
fn await_healthy(ids: &[String]) {
    let t0 = Instant::now();
    loop {
        let states: Vec<String> = ids
            .iter()
            .map(|id| docker(&["inspect", "-f", "{{.State.Health.Status}}", id]))
            .collect();
        if states.iter().all(|s| s == "healthy") {
            return;
        }
        let logs: Vec<String> = ids.iter().map(|id| logs_of(id)).collect();
        assert!(
            !states.iter().any(|s| s == "unhealthy") && t0.elapsed() < Duration::from_secs(180),
            "containers {ids:?}: {states:?}\n{}",
            logs.join("\n---\n")
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

fn logs_of(id: &str) -> String {
    let out = Command::new("docker").args(["logs", id]).output().unwrap();
    String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr)
}

/// The loopback address Docker published a container's port 8080 on.
fn published(id: &str) -> String {
    let port = docker(&["port", id, "8080"]);
    let addr = port.lines().find(|l| l.starts_with("127.0.0.1:")).unwrap();
    format!("http://{addr}")
}

fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

fn get(base: &str, token: &str, path: &str) -> (u16, Vec<u8>) {
    let r = client()
        .get(format!("{base}{path}"))
        .bearer_auth(token)
        .send()
        .unwrap();
    (r.status().as_u16(), r.bytes().unwrap().to_vec())
}

fn get_json(base: &str, token: &str, path: &str) -> Value {
    let (status, body) = get(base, token, path);
    assert_eq!(status, 200, "{path}: {}", String::from_utf8_lossy(&body));
    serde_json::from_slice(&body).unwrap()
}

fn submit(base: &str, token: &str, params: &Value) -> i64 {
    let r = client()
        .post(format!("{base}/api/jobs"))
        .bearer_auth(token)
        .json(&json!({"scene_name": "cornell_mirror_glass", "params": params}))
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 202);
    r.json::<Value>().unwrap()["id"].as_i64().unwrap()
}

/// Wait for job `id` to end; its EXR.
fn await_exr(base: &str, token: &str, id: i64) -> Vec<u8> {
    let t0 = Instant::now();
    loop {
        let job = get_json(base, token, &format!("/api/jobs/{id}"));
        if job["status"] != "queued" && job["status"] != "running" {
            assert_eq!(job["status"], "done", "{job}");
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(300), "{job}");
        std::thread::sleep(Duration::from_millis(100));
    }
    let (status, exr) = get(base, token, &format!("/api/jobs/{id}/image.exr"));
    assert_eq!(status, 200);
    exr
}

#[test]
fn the_image_runs_healthy_as_its_own_user_and_its_volume_outlives_the_container() {
    let image = image();
    let name = format!("photonbox-test-{}", std::process::id());
    let volume = format!("{name}-data");
    let _cleanup = Cleanup(vec![
        vec![
            "docker".into(),
            "volume".into(),
            "rm".into(),
            volume.clone(),
        ],
        vec![
            "docker".into(),
            "rm".into(),
            "-f".into(),
            format!("{name}-a"),
        ],
        vec![
            "docker".into(),
            "rm".into(),
            "-f".into(),
            format!("{name}-b"),
        ],
    ]);
    let start = |suffix: &str| -> String {
        let id = docker(&[
            "run",
            "-d",
            "--name",
            &format!("{name}-{suffix}"),
            "-p",
            "127.0.0.1::8080",
            "-v",
            &format!("{volume}:/data"),
            image,
        ]);
        await_healthy(std::slice::from_ref(&id));
        id
    };
    let first = start("a");

    // Non-root: the image's user, and the server process (pid 1) itself.
    assert_eq!(
        docker(&["inspect", "-f", "{{.Config.User}}", &first]),
        "photonbox"
    );
    let status = docker(&["exec", &first, "cat", "/proc/1/status"]);
    let uid = status.lines().find(|l| l.starts_with("Uid:")).unwrap();
    assert_eq!(
        uid.split_whitespace().nth(1),
        Some("10001"),
        "pid 1 runs as {uid}"
    );

    let base = published(&first);
    let token = docker(&["exec", &first, "cat", "/data/admin-token"]);
    let params = json!({"integrator": "photon", "photons": 2000, "caustic_photons": 2000,
                        "width": 24, "height": 18, "seed": 5});
    let id = submit(&base, &token, &params);
    let exr = await_exr(&base, &token, id);
    assert_eq!(
        exr,
        render_exr_by_cli(&params),
        "the container's EXR is not the CLI's"
    );
    let (status, png) = get(&base, &token, &format!("/api/jobs/{id}/image.png"));
    assert_eq!(status, 200);
    assert!(png.starts_with(b"\x89PNG"));

    // A new container on the same volume: the same admin, job and images.
    docker(&["rm", "-f", &first]);
    let second = start("b");
    let base = published(&second);
    let job = get_json(&base, &token, &format!("/api/jobs/{id}"));
    assert_eq!(job["status"], "done", "{job}");
    assert_eq!(
        get(&base, &token, &format!("/api/jobs/{id}/image.png")).1,
        png
    );
    assert_eq!(
        get(&base, &token, &format!("/api/jobs/{id}/image.exr")).1,
        exr
    );
}

/// `docker compose`, else Compose v1's `docker-compose`.
fn compose() -> Command {
    let v2 = Command::new("docker")
        .args(["compose", "version"])
        .output()
        .is_ok_and(|o| o.status.success());
    if v2 {
        let mut c = Command::new("docker");
        c.arg("compose");
        c
    } else {
        Command::new("docker-compose")
    }
}

#[test]
fn the_compose_farm_spreads_a_job_over_both_workers_to_the_cli_s_bytes() {
    let image = image();
    let project = format!("photonboxtest{}", std::process::id());
    let file = format!("{ROOT}/examples/compose.yaml");
    let compose_in = || {
        let mut c = compose();
        c.args(["-p", &project, "-f", &file])
            .env("PHOTONBOX_IMAGE", image)
            .env("POSTGRES_IMAGE", "photonbox/postgres:15")
            .env("PHOTONBOX_PUBLISH", "127.0.0.1:");
        for (k, v) in BUILD_ARGS {
            c.env(k, v);
        }
        c
    };
    let mut down = compose_in();
    down.args(["down", "-v", "--timeout", "5"]);
    let _down = Down(down);
    run(compose_in().args(["up", "-d"]));

    let services = ["api", "worker-1", "worker-2"];
    let ids: Vec<String> = services
        .iter()
        .map(|s| run(compose_in().args(["ps", "-q", s])))
        .collect();
    await_healthy(&ids);
    let base = published(&ids[0]);
    let logs = logs_of(&ids[0]);
    let token = logs
        .lines()
        .find_map(|l| l.split("admin token (shown once): ").nth(1))
        .unwrap_or_else(|| panic!("no admin token in the API's log:\n{logs}"))
        .trim()
        .to_string();

    let params = json!({"integrator": "ppm", "photons": 3000, "caustic_photons": 3000,
                        "iterations": 48, "width": 40, "height": 30, "seed": 11});
    let id = submit(&base, &token, &params);
    let exr = await_exr(&base, &token, id);
    assert_eq!(
        exr,
        render_exr_by_cli(&params),
        "the farm's EXR is not the CLI's"
    );

    let workers = get_json(&base, &token, "/api/workers")["workers"].clone();
    let done: Vec<(String, i64)> = workers
        .as_array()
        .unwrap()
        .iter()
        .map(|w| {
            (
                w["id"].as_str().unwrap().to_string(),
                w["tasks_done"].as_i64().unwrap(),
            )
        })
        .collect();
    assert_eq!(done.len(), 2, "{workers}");
    let tasks = get_json(&base, &token, &format!("/api/jobs/{id}"))["stats"]["farm"]["tasks"]
        .as_i64()
        .unwrap();
    assert_eq!(done.iter().map(|d| d.1).sum::<i64>(), tasks, "{workers}");
    assert!(
        done.iter().all(|d| d.1 > 0),
        "one worker did it all: {workers}"
    );
}

/// `compose down`, however the test ends.
struct Down(Command);

impl Drop for Down {
    fn drop(&mut self) {
        let _ = self.0.output();
    }
}
