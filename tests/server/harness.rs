//! A real `photonbox serve` on an ephemeral port with a temporary data folder, and a small
//! blocking client for it (JSON calls and Server-Sent Events).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use reqwest::blocking::{Client, Response};
use serde_json::Value;

pub struct Server {
    child: Child,
    pub base: String,
    pub data: PathBuf,
    pub admin: String,
    /// The sign-in URL the server printed (`{base}/?token=...`, the admin's token).
    pub sign_in: String,
}

impl Server {
    /// Start a server on `data` with extra flags; returns once it listens.
    pub fn start(data: &Path, flags: &[&str]) -> Server {
        Server::start_limited(data, flags, None)
    }

    /// As `start`, with the process's descriptor limit (soft and hard) set to `nofile`.
    pub fn start_limited(data: &Path, flags: &[&str], nofile: Option<u64>) -> Server {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_photonbox"));
        cmd.args(["serve", "--addr", "127.0.0.1:0", "--threads", "2", "--data"])
            .arg(data)
            .args(flags)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        if let Some(n) = nofile {
            use std::os::unix::process::CommandExt;
            // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
            unsafe {
                cmd.pre_exec(move || {
                    let lim = libc::rlimit {
                        rlim_cur: n,
                        rlim_max: n,
                    };
                    if libc::setrlimit(libc::RLIMIT_NOFILE, &lim) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                    Ok(())
                });
            }
        }
        let mut child = cmd.spawn().expect("start photonbox serve");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        let first = lines.next().expect("server output").unwrap();
        let base = first
            .strip_prefix("photonbox: listening on ")
            .unwrap_or_else(|| panic!("unexpected first line: {first}"))
            .to_string();
        let second = lines.next().expect("gallery line").unwrap();
        assert!(
            second.contains(&format!("{base}/?token=")),
            "the server prints a sign-in URL: {second}"
        );
        let sign_in = second[second.find(&base).unwrap()..].trim().to_string();
        // Keep draining stdout so the server never blocks on a full pipe.
        std::thread::spawn(move || for _ in lines {});
        let admin = std::fs::read_to_string(data.join("admin-token"))
            .unwrap()
            .trim()
            .to_string();
        Server {
            child,
            base,
            data: data.to_path_buf(),
            admin,
            sign_in,
        }
    }

    /// SIGKILL: no chance to clean up.
    pub fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// SIGTERM, and wait for the process to exit: its status and how long that took.
    pub fn terminate(mut self) -> (std::process::ExitStatus, f64) {
        let t0 = std::time::Instant::now();
        // SAFETY: sending a signal to our own child process.
        unsafe {
            libc::kill(self.child.id() as i32, libc::SIGTERM);
        }
        let status = self.child.wait().unwrap();
        (status, t0.elapsed().as_secs_f64())
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// host:port, for raw TCP clients.
    pub fn addr(&self) -> String {
        self.base.trim_start_matches("http://").to_string()
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// Add a user with `photonbox user add` (while the server runs); returns its token.
    pub fn add_user(&self, name: &str) -> String {
        user_add(&self.data, name)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `photonbox user add NAME --data DATA`: the new user's token.
pub fn user_add(data: &Path, name: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_photonbox"))
        .args(["user", "add", name, "--data"])
        .arg(data)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

pub fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(300))
        .build()
        .unwrap()
}

pub fn json_of(r: Response) -> (u16, Value) {
    let status = r.status().as_u16();
    let text = r.text().unwrap();
    let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
    (status, v)
}

pub fn get(s: &Server, token: &str, path: &str) -> (u16, Value) {
    json_of(client().get(s.url(path)).bearer_auth(token).send().unwrap())
}

pub fn post(s: &Server, token: &str, body: &Value) -> (u16, Value) {
    json_of(
        client()
            .post(s.url("/api/jobs"))
            .bearer_auth(token)
            .json(body)
            .send()
            .unwrap(),
    )
}

pub fn delete(s: &Server, token: &str, id: i64) -> (u16, Value) {
    json_of(
        client()
            .delete(s.url(&format!("/api/jobs/{id}")))
            .bearer_auth(token)
            .send()
            .unwrap(),
    )
}

/// Submit and return the new job's id (asserting 202).
pub fn submit(s: &Server, token: &str, body: Value) -> i64 {
    let (status, v) = post(s, token, &body);
    assert_eq!(status, 202, "{v}");
    assert_eq!(v["status"], "queued");
    v["id"].as_i64().unwrap()
}

/// One Server-Sent Event.
#[derive(Debug, Clone)]
pub struct SseEvent {
    pub name: String,
    pub data: Value,
}

/// Follow a job's events, calling `on_event` for each, until `stop` says so or the stream
/// ends; returns every event seen.
pub fn follow(
    s: &Server,
    token: &str,
    id: i64,
    mut stop: impl FnMut(&SseEvent) -> bool,
) -> Vec<SseEvent> {
    let resp = client()
        .get(s.url(&format!("/api/jobs/{id}/events")))
        .bearer_auth(token)
        .send()
        .unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    let mut out = Vec::new();
    let (mut name, mut data) = (String::new(), String::new());
    for line in BufReader::new(resp).lines() {
        let Ok(line) = line else { break };
        if let Some(v) = line.strip_prefix("event: ") {
            name = v.to_string();
        } else if let Some(v) = line.strip_prefix("data: ") {
            data = v.to_string();
        } else if line.is_empty() && !name.is_empty() {
            let ev = SseEvent {
                name: std::mem::take(&mut name),
                data: serde_json::from_str(&data).unwrap_or(Value::Null),
            };
            let done = stop(&ev);
            out.push(ev);
            if done {
                break;
            }
        }
    }
    out
}

/// Follow a job to its final event and return the events.
pub fn follow_to_end(s: &Server, token: &str, id: i64) -> Vec<SseEvent> {
    let evs = follow(s, token, id, |e| {
        matches!(e.name.as_str(), "done" | "failed" | "cancelled")
    });
    let last = evs.last().expect("events");
    assert!(
        matches!(last.name.as_str(), "done" | "failed" | "cancelled"),
        "stream ended without a final event: {evs:?}"
    );
    evs
}

/// Wait (on the event stream, not by sleeping) until the job is rendering.
pub fn wait_running(s: &Server, token: &str, id: i64) {
    let evs = follow(s, token, id, |e| {
        e.data["status"] == "running" && e.data["progress"].as_f64().unwrap_or(0.0) > 0.0
            || e.data["status"] != "queued" && e.data["status"] != "running"
    });
    assert_eq!(
        evs.last().unwrap().data["status"],
        "running",
        "job {id} should be running: {evs:?}"
    );
}

pub fn bytes(s: &Server, token: &str, path: &str) -> (u16, Vec<u8>) {
    let r = client().get(s.url(path)).bearer_auth(token).send().unwrap();
    (r.status().as_u16(), r.bytes().unwrap().to_vec())
}

/// The server's Prometheus text.
pub fn metrics(s: &Server) -> String {
    client()
        .get(s.url("/metrics"))
        .send()
        .unwrap()
        .text()
        .unwrap()
}

/// Follow job `id` to its end and assert that it is done.
pub fn expect_done(s: &Server, token: &str, id: i64) -> Vec<SseEvent> {
    let evs = follow_to_end(s, token, id);
    assert_eq!(evs.last().unwrap().name, "done", "job {id}: {evs:?}");
    evs
}

/// Submit a job, follow it to its end and assert that it is done; returns its id.
pub fn run_to_done(s: &Server, token: &str, body: Value) -> i64 {
    let id = submit(s, token, body);
    expect_done(s, token, id);
    id
}
