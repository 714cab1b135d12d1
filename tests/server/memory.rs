//! Memory truth: the estimate a job is admitted by bounds the server's peak while it renders,
//! on the largest job the limits accept of each integrator, and a finished job gives its
//! memory back.

use serde_json::{Value, json};

use super::harness::*;

/// Resident and peak resident memory of a process (VmRSS, VmHWM), in bytes.
pub fn rss(pid: u32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let kb = |key: &str| -> u64 {
        let line = status.lines().find(|l| l.starts_with(key)).unwrap();
        line.split_whitespace()
            .nth(1)
            .unwrap()
            .parse::<u64>()
            .unwrap()
            << 10
    };
    (kb("VmRSS:"), kb("VmHWM:"))
}

pub fn reset_peak(pid: u32) {
    // "5" resets the peak resident set size (proc(5)).
    std::fs::write(format!("/proc/{pid}/clear_refs"), "5").unwrap();
}

/// The Cornell box with a height-field mesh of `n` x `n` quads (2 n^2 triangles) on its floor.
fn cornell_with_mesh(n: usize) -> Value {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell.json"))
        .unwrap();
    let mut scene: Value = serde_json::from_str(&text).unwrap();
    let mut positions = Vec::with_capacity((n + 1) * (n + 1));
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            let h = 0.05 * ((u * 40.0).sin() * (v * 40.0).cos() + 1.0);
            let r = |x: f64| (x * 1e4).round() / 1e4;
            positions.push(json!([r(1.0 + 3.5 * u), r(h), r(1.0 + 3.5 * v)]));
        }
    }
    let mut triangles = Vec::with_capacity(2 * n * n);
    let at = |i: usize, j: usize| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            triangles.push(json!([at(i, j), at(i + 1, j), at(i + 1, j + 1)]));
            triangles.push(json!([at(i, j), at(i + 1, j + 1), at(i, j + 1)]));
        }
    }
    scene["objects"].as_array_mut().unwrap().push(json!({
        "type": "mesh", "material": "white", "positions": positions, "triangles": triangles
    }));
    scene
}

/// Run `job` on `s`; the growth of the server's peak memory over its memory before the job,
/// the job's estimate, and the memory held after it finished (over before).
fn measure(s: &Server, job: Value) -> (u64, u64, i64) {
    let (before, _) = rss(s.pid());
    let id = submit(s, &s.admin, job);
    reset_peak(s.pid());
    expect_done(s, &s.admin, id);
    let (after, peak) = rss(s.pid());
    let (_, v) = get(s, &s.admin, &format!("/api/jobs/{id}"));
    let estimate = v["memory_estimate_bytes"].as_u64().unwrap();
    (
        peak.saturating_sub(before),
        estimate,
        after as i64 - before as i64,
    )
}

#[test]
fn the_memory_estimate_bounds_the_peak_of_the_largest_accepted_jobs() {
    let dir = tempfile::tempdir().unwrap();
    // Limits small enough for a test, the same code path as the defaults.
    let s = Server::start(
        dir.path(),
        &[
            "--max-pixels",
            "4194304",
            "--max-photons",
            "2000000",
            "--max-triangles",
            "250000",
            "--cache-mb",
            "0",
        ],
    );
    let mesh = cornell_with_mesh(350); // 245,000 triangles
    let jobs = [
        (
            "raytrace, mesh",
            json!({"scene": mesh, "params": {"integrator": "raytrace",
            "width": 2048, "height": 2048, "spp": 1}}),
        ),
        (
            "photon",
            json!({"scene_name": "cornell_mirror_glass", "params": {"integrator": "photon", 
            "width": 1024, "height": 1024, "photons": 2000000, "caustic_photons": 2000000,
            "spp": 1, "gather_rays": 0}}),
        ),
        (
            "ppm",
            json!({"scene_name": "cornell_mirror_glass", "params": {"integrator": "ppm",
            "width": 1024, "height": 1024, "photons": 2000000, "caustic_photons": 2000000,
            "iterations": 2, "spp": 1}}),
        ),
        // The largest image, with few photons: what grows with the pixels (film, pass
        // sums, the saved state and previews).
        (
            "ppm, pixels",
            json!({"scene_name": "cornell", "params": {"integrator": "ppm",
            "width": 2048, "height": 2048, "photons": 10000, "caustic_photons": 0,
            "iterations": 3, "spp": 1}}),
        ),
        (
            "photon, pixels",
            json!({"scene_name": "cornell", "params": {"integrator": "photon", 
            "width": 2048, "height": 2048, "photons": 10000, "caustic_photons": 0,
            "spp": 1, "gather_rays": 0}}),
        ),
    ];
    let mut report = Vec::new();
    for (name, job) in jobs {
        let (grew, estimate, held) = measure(&s, job);
        report.push(format!(
            "{name}: peak +{} MiB, estimate {} MiB, held after {} MiB",
            grew >> 20,
            estimate >> 20,
            held >> 20
        ));
        assert!(grew <= estimate, "{}", report.join("; "));
        // Given back: what stays is a small fraction of the peak (before the fix: 87%).
        assert!(
            held < (grew / 3) as i64 + (32 << 20),
            "{}",
            report.join("; ")
        );
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
fn uploaded_scenes_stay_in_the_store_not_in_the_servers_memory() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell.json"))
        .unwrap();
    let mut scene: Value = serde_json::from_str(&text).unwrap();
    // 6 MB of scene text a job (a description is kept with the scene, like a mesh).
    scene["description"] = json!("d".repeat(6 << 20));
    let job = json!({"scene": scene, "params": {"integrator": "raytrace", "width": 8,
        "height": 8, "spp": 1}});
    // The allocator's working set settles over the first few jobs.
    for _ in 0..4 {
        run_to_done(&s, &s.admin, job.clone());
    }
    // What the server holds (heap in use), not what its allocator keeps resident for
    // reuse: that depends on how threads met under the machine's load (24-50 MiB more
    // resident under a concurrent build, with nothing more held).
    let before = heap_in_use(&s);
    for _ in 0..12 {
        run_to_done(&s, &s.admin, job.clone());
    }
    let (status, list) = get(&s, &s.admin, "/api/jobs");
    assert_eq!(status, 200);
    assert_eq!(list["jobs"].as_array().unwrap().len(), 16);
    let grew = heap_in_use(&s) as i64 - before as i64;
    // Held in memory, twelve scenes would be 72 MiB.
    assert!(
        grew < 12 << 20,
        "twelve more 6 MB scenes grew the server by {} MiB",
        grew >> 20
    );
}

/// The server's heap in use (its `/metrics`).
fn heap_in_use(s: &Server) -> u64 {
    let text = metrics(s);
    let line = text
        .lines()
        .find(|l| l.starts_with("photonbox_heap_in_use_bytes "))
        .expect("the server reports its heap in use");
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

/// Many large uploads at once: the server reads and admits a bounded number of bodies at
/// a time (four of the largest, `server::body`), so its peak does not grow with the
/// number of clients sending one.
#[test]
fn many_large_uploads_at_once_share_a_bounded_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let limit = 4 << 20;
    let s = Server::start(dir.path(), &["--max-body", &limit.to_string()]);
    // Refused by the work limit, after the scene is parsed and checked.
    let params = json!({"integrator": "ppm", "width": 4096, "height": 4096, "spp": 4096,
                        "gather_rays": 14000});
    let body = json!({"scene": cornell_with_mesh(235), "params": params});
    let body = serde_json::to_vec(&body).unwrap();
    assert!(
        body.len() > limit * 3 / 4 && body.len() < limit,
        "{}",
        body.len()
    );
    let (before, _) = rss(s.pid());
    reset_peak(s.pid());
    let statuses: Vec<u16> = std::thread::scope(|scope| {
        let sends: Vec<_> = (0..128)
            .map(|_| {
                scope.spawn(|| {
                    let send = || {
                        client()
                            .post(s.url("/api/jobs"))
                            .bearer_auth(&s.admin)
                            .header("content-type", "application/json")
                            .body(body.clone())
                            .send()
                    };
                    // A request the network failed is sent again, as a client would. Twice
                    // in CI runs of 2026-12-04, on hosts of two cores, some of the 128
                    // connections failed with ETIMEDOUT: once at connect, once on an open
                    // connection within the test's 86 s, consistent with reqwest's
                    // keepalive (15 s idle, then 3 probes 15 s apart) going unanswered
                    // while 124 bodies of 4 MiB waited to be read. Not reproduced locally;
                    // cause not found. An HTTP answer other than 422, a third failure, or
                    // any other error fails the test.
                    let again = |e: reqwest::Error| {
                        if e.is_connect() || e.is_request() {
                            send()
                        } else {
                            Err(e)
                        }
                    };
                    let r = send().or_else(again).or_else(again).unwrap();
                    r.status().as_u16()
                })
            })
            .collect();
        sends.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let (_, peak) = rss(s.pid());
    assert!(statuses.iter().all(|&c| c == 422), "{statuses:?}");
    // About ten times a body for each of the four admitted at once, 160 MiB (measured:
    // 201-217 MiB); read all at once, the 128 bodies' bytes alone are 512 MiB (measured
    // without the budget: 634 MiB).
    let grew = peak.saturating_sub(before);
    assert!(grew < 400 << 20, "the peak grew by {} MiB", grew >> 20);
}

/// One user's slow uploads hold at most one share of the body budget: another user's
/// upload is read and admitted at once, not once the first user's bodies time out.
#[test]
fn one_user_s_slow_uploads_do_not_hold_up_another_user_s() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let limit = 4 << 20;
    let flags = ["--max-body", &limit.to_string(), "--body-timeout", "60"];
    let s = Server::start(dir.path(), &flags);
    let bob = s.add_user("bob");
    // Four uploads by the admin that declare nearly the limit and send one byte: together
    // they would hold nearly the whole budget for the body timeout.
    let slow: Vec<std::net::TcpStream> = (0..4)
        .map(|_| {
            let mut c = std::net::TcpStream::connect(s.addr()).unwrap();
            write!(
                c,
                "POST /api/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {}\r\n\
                 Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{{",
                s.admin,
                limit - 1000
            )
            .unwrap();
            c
        })
        .collect();
    // Bob's upload of about 1 MB: parsed and checked (refused by the work limit) at once.
    let params = json!({"integrator": "ppm", "width": 4096, "height": 4096, "spp": 4096,
                        "gather_rays": 14000});
    let body = json!({"scene": cornell_with_mesh(120), "params": params});
    let t0 = std::time::Instant::now();
    let (status, v) = post(&s, &bob, &body);
    let waited = t0.elapsed();
    assert_eq!((status, v["path"].as_str()), (422, Some("params")), "{v}");
    assert!(waited.as_secs_f64() < 20.0, "bob waited {waited:?}");
    drop(slow);
}
