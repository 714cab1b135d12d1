//! What a hostile or careless client tried beyond the connection (docs/security.md), each
//! held by a test here: a compute limit, streamed downloads, cancel inside
//! the camera pass, corrupt ppm states, ids never reused after the store lost rows, the
//! admin never locked out, one server per data folder. (The storage quota: tests/farm/limits.rs,
//! on one box and on the farm.)

use serde_json::{Value, json};

use super::harness::*;
use super::memory::{reset_peak, rss};

#[test]
fn a_job_over_the_compute_limit_is_refused_with_its_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    // About 10^15 samples: 4096^2 pixels x 4096 spp x (1 + 14000 gather rays).
    let (status, v) = post(
        &s,
        &s.admin,
        &json!({"scene_name": "cornell", "params": {"integrator": "photon", "width": 4096, "height": 4096,
                "spp": 4096, "gather_rays": 14000, "photons": 1000, "caustic_photons": 0}}),
    );
    assert_eq!(status, 422, "{v}");
    assert_eq!(v["path"], "params", "{v}");
    let msg = v["error"].as_str().unwrap();
    let work = 4096f64.powi(3) * 14001.0 + 1000.0 + 1000.0 / 4.0 * 50.0;
    assert!(
        msg.contains(&format!("{work:.3e}")),
        "the estimate ({work:.3e}) is in the error: {msg}"
    );
    // The same job, 4096 times smaller, is fine.
    let (status, v) = post(
        &s,
        &s.admin,
        &json!({"scene_name": "cornell", "params": {"integrator": "photon", "width": 64, "height": 64,
                "spp": 1, "gather_rays": 16, "photons": 1000, "caustic_photons": 0}}),
    );
    assert_eq!(status, 202, "{v}");
}

/// A time limit without a pass count runs passes until the time is spent (issue 20, item
/// 5): the pass limit counts the passes a job asks for, and such a job asks for none.
#[test]
fn a_time_limit_alone_runs_passes_until_it_is_spent() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let small = json!({"integrator": "ppm", "width": 16, "height": 12, "photons": 500,
                       "caustic_photons": 500});
    let mut timed = small.clone();
    timed["time_limit"] = json!(0.5);
    let id = run_to_done(
        &s,
        &s.admin,
        json!({"scene_name": "cornell", "params": timed}),
    );
    let (_, job) = get(&s, &s.admin, &format!("/api/jobs/{id}"));
    let passes = &job["stats"]["ppm"];
    assert_eq!(passes["stopped_by"], "time_limit", "{job}");
    // Far more passes than the default 16 fit in half a second of passes this small.
    assert!(passes["passes"].as_u64().unwrap() > 16, "{job}");
    // The job's params say what was asked: no pass count (not the engine's most passes,
    // which the pass limit would refuse were they sent again).
    assert!(job["params"]["iterations"].is_null(), "{job}");
    // A pass count over the limit is still refused, with or without a time limit.
    let mut many = small;
    many["iterations"] = json!(200_000);
    many["time_limit"] = json!(0.5);
    let (status, v) = post(
        &s,
        &s.admin,
        &json!({"scene_name": "cornell", "params": many}),
    );
    assert_eq!(
        (status, v["path"].as_str()),
        (422, Some("params.iterations")),
        "{v}"
    );
    // The work limit counts one pass of such a job: 2048^2 samples of pt a pass fit (as a
    // million passes they would not), a pass of 10^15 samples does not.
    let big = json!({"integrator": "pt", "width": 2048, "height": 2048, "time_limit": 60});
    let (status, v) = post(
        &s,
        &s.admin,
        &json!({"scene_name": "cornell", "params": big}),
    );
    assert_eq!(status, 202, "{v}");
    delete(&s, &s.admin, v["id"].as_i64().unwrap());
    let huge = json!({"integrator": "ppm", "width": 4096, "height": 4096, "spp": 4096,
                      "gather_rays": 14000, "time_limit": 60});
    let (status, v) = post(
        &s,
        &s.admin,
        &json!({"scene_name": "cornell", "params": huge}),
    );
    assert_eq!((status, v["path"].as_str()), (422, Some("params")), "{v}");
    let error = v["error"].as_str().unwrap();
    assert!(error.starts_with("one pass of this job is"), "{v}");
}

#[test]
fn downloads_are_streamed_with_range_and_head() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let id = run_to_done(
        &s,
        &s.admin,
        json!({"scene_name": "cornell", "params": {"integrator": "raytrace",
               "width": 2048, "height": 2048, "spp": 1}}),
    );
    let path = format!("/api/jobs/{id}/image.exr");
    let file = std::fs::read(dir.path().join("results").join(format!("{id}.exr"))).unwrap();
    assert!(file.len() > 24 << 20, "a large EXR: {} bytes", file.len());
    // HEAD: the length, no body.
    let r = client()
        .head(s.url(&path))
        .bearer_auth(&s.admin)
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(
        r.headers()["content-length"],
        file.len().to_string().as_str()
    );
    assert_eq!(r.headers()["content-type"], "image/x-exr");
    assert_eq!(r.bytes().unwrap().len(), 0);
    // Range: the bytes asked for.
    let r = client()
        .get(s.url(&path))
        .bearer_auth(&s.admin)
        .header("Range", "bytes=1000-1999")
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 206);
    assert_eq!(&r.bytes().unwrap()[..], &file[1000..2000]);
    // Eight clients at once: the server's memory does not grow by the file eight times
    // over (nor once: it streams).
    reset_peak(s.pid());
    let (_, before) = rss(s.pid());
    let barrier = std::sync::Barrier::new(8);
    std::thread::scope(|scope| {
        for _ in 0..8 {
            scope.spawn(|| {
                barrier.wait();
                let (status, body) = bytes(&s, &s.admin, &path);
                assert_eq!(status, 200);
                assert!(body == file, "a download differs from the file");
            });
        }
    });
    let grew = rss(s.pid()).1.saturating_sub(before);
    eprintln!(
        "8 parallel downloads of a {} MB EXR: server peak +{} MB",
        file.len() >> 20,
        grew >> 20
    );
    assert!(
        grew < file.len() as u64 / 2,
        "8 downloads of a {} MB file grew the server by {} MB",
        file.len() >> 20,
        grew >> 20
    );
}

fn sqlite_files(data: &std::path::Path) -> Vec<std::path::PathBuf> {
    [
        "photonbox.sqlite3",
        "photonbox.sqlite3-wal",
        "photonbox.sqlite3-shm",
    ]
    .iter()
    .map(|f| data.join(f))
    .collect()
}

#[test]
fn a_store_that_lost_rows_never_hands_old_results_to_new_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path();
    let s = Server::start(data, &[]);
    let bob = s.add_user("bob");
    // The store as it was before alice's job: users only.
    let alice = s.add_user("alice");
    s.kill();
    let saved = tempfile::tempdir().unwrap();
    for f in sqlite_files(data) {
        if f.exists() {
            std::fs::copy(&f, saved.path().join(f.file_name().unwrap())).unwrap();
        }
    }
    let s = Server::start(data, &[]);
    let old = run_to_done(
        &s,
        &alice,
        json!({"scene_name": "cornell", "params": {"integrator": "raytrace", "width": 16,
               "height": 16, "spp": 1}}),
    );
    s.kill();
    // The crash took the job's rows: the store is back to what it was before.
    for f in sqlite_files(data) {
        let _ = std::fs::remove_file(&f);
        let from = saved.path().join(f.file_name().unwrap());
        if from.exists() {
            std::fs::copy(&from, &f).unwrap();
        }
    }
    let s = Server::start(data, &[]);
    // The old job's files are set aside, not served.
    // (in a folder of this start's own under results/orphaned)
    let starts: Vec<_> = std::fs::read_dir(data.join("results").join("orphaned"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(starts.len(), 1, "{starts:?}");
    assert!(starts[0].join(format!("{old}.png")).is_file());
    assert!(!data.join("results").join(format!("{old}.png")).exists());
    for t in [&bob, &alice, &s.admin] {
        assert_eq!(bytes(&s, t, &format!("/api/jobs/{old}/image.png")).0, 404);
    }
    // New jobs get new ids, and no image until they render one.
    for _ in 0..5 {
        let (status, v) = post(
            &s,
            &bob,
            &json!({"scene_name": "cornell", "params": {"integrator": "photon", "photons": 20000000, "width": 16,
                    "height": 16, "spp": 1, "gather_rays": 0}}),
        );
        assert_eq!(status, 202, "{v}");
        let id = v["id"].as_i64().unwrap();
        assert_ne!(id, old, "an id was reused");
        assert!(id > 0 && id < 1 << 53, "ids are exact in JavaScript: {id}");
        assert_eq!(bytes(&s, &bob, &format!("/api/jobs/{id}/image.png")).0, 404);
        delete(&s, &bob, id);
    }
}

#[test]
fn the_admin_is_never_locked_out_by_a_lost_store() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path();
    let s = Server::start(data, &[]);
    let admin = s.admin.clone();
    s.kill();
    for f in sqlite_files(data) {
        let _ = std::fs::remove_file(f);
    }
    let s = Server::start(data, &[]);
    assert_eq!(s.admin, admin, "the admin-token file is kept");
    let (status, me) = get(&s, &admin, "/api/me");
    assert_eq!(status, 200, "{me}");
    assert_eq!(me["admin"], true);
}

#[test]
fn user_add_before_the_first_serve_creates_the_store_and_the_admin() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("fresh");
    let alice = user_add(&data, "alice");
    assert!(
        data.join("admin-token").is_file(),
        "the admin's token is written"
    );
    // `start` asserts the sign-in URL with the admin's token.
    let s = Server::start(&data, &[]);
    let (status, me) = get(&s, &s.admin, "/api/me");
    assert_eq!((status, &me["admin"]), (200, &Value::Bool(true)), "{me}");
    let (status, me) = get(&s, &alice, "/api/me");
    assert_eq!((status, &me["name"]), (200, &json!("alice")), "{me}");
}

#[test]
fn cancel_stops_the_most_expensive_camera_pass_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    // One pixel sample of this job is 1 + 256 rays, and every tile holds 4096 samples a
    // pixel: minutes a tile, so cancel must act inside a tile.
    let id = submit(
        &s,
        &s.admin,
        json!({"scene_name": "cornell", "params": {"integrator": "photon", "width": 64, "height": 64, "spp": 4096,
               "gather_rays": 256, "photons": 1000, "caustic_photons": 0}}),
    );
    // Wait until the camera pass runs (its progress events name the phase).
    let evs = follow(&s, &s.admin, id, |e| {
        e.data["phase"] == "render" || e.data["status"] != "running" && e.data["status"] != "queued"
    });
    assert_eq!(evs.last().unwrap().data["phase"], "render", "{evs:?}");
    let t0 = std::time::Instant::now();
    let (status, v) = delete(&s, &s.admin, id);
    let took = t0.elapsed();
    assert_eq!(status, 200, "{v}");
    // DELETE waits (at most a few seconds) for the render to stop: it stopped in that time.
    assert_eq!(v["status"], "cancelled", "{v} after {took:?}");
    eprintln!("cancelled inside the camera pass; DELETE answered after {took:?}");
}

#[test]
fn a_corrupt_ppm_state_restarts_the_job_from_pass_0() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &["--max-running", "1"]);
    let t = s.admin.clone();
    let job = json!({"scene_name": "cornell_mirror_glass", "params": {"integrator": "ppm",
        "iterations": 40, "width": 48, "height": 32, "photons": 30000,
        "caustic_photons": 30000}});
    let id = submit(&s, &t, job.clone());
    follow(&s, &t, id, |e| {
        e.data["previews"].as_u64().unwrap_or(0) >= 3
    });
    s.kill();
    // One flipped bit in the middle of the saved sum.
    let state = dir.path().join("results").join(format!("{id}.ppmstate"));
    let mut bytes_ = std::fs::read(&state).unwrap();
    let mid = bytes_.len() / 2;
    bytes_[mid] ^= 0x10;
    std::fs::write(&state, &bytes_).unwrap();

    let s = Server::start(dir.path(), &["--max-running", "1"]);
    expect_done(&s, &t, id);
    let (_, v) = get(&s, &t, &format!("/api/jobs/{id}"));
    let note = &v["stats"]["ppm_state"];
    assert_eq!(note["resumed_from_pass"], 0, "{note}");
    assert!(
        note["discarded"].as_str().unwrap_or("").contains("corrupt"),
        "the job says why it started over: {note}"
    );
    // From pass 0, the same bytes as a job never interrupted.
    let again = run_to_done(&s, &t, job);
    let (_, a) = bytes(&s, &t, &format!("/api/jobs/{id}/image.exr"));
    let (_, b) = bytes(&s, &t, &format!("/api/jobs/{again}/image.exr"));
    assert!(
        a == b,
        "the restarted job's EXR differs from an uninterrupted one"
    );
}

#[test]
fn a_second_server_on_the_same_data_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let mut second = std::process::Command::new(env!("CARGO_BIN_EXE_photonbox"))
        .args(["serve", "--addr", "127.0.0.1:0", "--data"])
        .arg(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // A refused server exits without a word on stdout; one that starts says it listens.
    let mut first_line = String::new();
    let mut stdout = std::io::BufReader::new(second.stdout.take().unwrap());
    std::io::BufRead::read_line(&mut stdout, &mut first_line).unwrap();
    if first_line.contains("listening") {
        let _ = second.kill();
        panic!("a second server started on the same data folder: {first_line}");
    }
    let out = second.wait_with_output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("in use by another"), "{err}");
    // The first one is untouched.
    let (status, _) = get(&s, &s.admin, "/api/me");
    assert_eq!(status, 200);
}
