//! Integration tests of `photonbox serve`: each starts a real server on an ephemeral port
//! with a temporary data folder and talks to it over HTTP.

mod connections;
mod hardening;
mod harness;
mod memory;
mod same_bytes;

use std::time::Instant;

use harness::*;
use serde_json::{Value, json};

/// A job that renders in a fraction of a second.
fn small(scene: &str) -> Value {
    json!({
        "scene_name": scene,
        "params": {"integrator": "photon", "width": 48, "height": 32, "photons": 20000, "caustic_photons": 20000,
                   "spp": 1, "gather_rays": 0, "k": 20}
    })
}

/// A job that takes many seconds (20M photons), for cancelling and fairness.
fn long() -> Value {
    json!({
        "scene_name": "cornell_mirror_glass",
        "params": {"integrator": "photon", "width": 64, "height": 64, "photons": 20000000, "caustic_photons": 1000,
                   "spp": 1, "gather_rays": 0}
    })
}

fn decode_exr(bytes: &[u8]) -> image::Rgb32FImage {
    image::load_from_memory_with_format(bytes, image::ImageFormat::OpenExr)
        .unwrap()
        .to_rgb32f()
}

#[test]
fn submit_follow_events_and_fetch_images() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let id = submit(&s, &s.admin, small("cornell"));
    let evs = follow_to_end(&s, &s.admin, id);
    let names: Vec<&str> = evs.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(
        names[0], "status",
        "a client first gets the current state: {names:?}"
    );
    assert!(names.contains(&"progress"), "{names:?}");
    assert!(names.contains(&"preview"), "{names:?}");
    assert_eq!(*names.last().unwrap(), "done", "{names:?}");
    // Progress never goes backwards.
    let progress: Vec<f64> = evs
        .iter()
        .filter(|e| e.name == "progress")
        .map(|e| e.data["progress"].as_f64().unwrap())
        .collect();
    assert!(progress.windows(2).all(|w| w[1] >= w[0]), "{progress:?}");
    assert_eq!(*progress.last().unwrap(), 1.0);

    let (status, job) = get(&s, &s.admin, &format!("/api/jobs/{id}"));
    assert_eq!(status, 200);
    assert_eq!(job["status"], "done");
    assert_eq!(job["progress"], 1.0);
    assert_eq!(job["stats"]["params"]["width"], 48);
    assert!(job["stats"]["times"]["total"].as_f64().unwrap() > 0.0);
    assert_eq!(job["stats"]["cache"]["photon_maps"], "miss");

    let (status, png) = bytes(&s, &s.admin, &format!("/api/jobs/{id}/image.png"));
    assert_eq!(status, 200);
    let png = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
    assert_eq!((png.width(), png.height()), (48, 32));
    let (status, exr) = bytes(&s, &s.admin, &format!("/api/jobs/{id}/image.exr"));
    assert_eq!(status, 200);
    let exr = decode_exr(&exr);
    assert_eq!((exr.width(), exr.height()), (48, 32));
    assert!(exr.pixels().all(|p| p.0.iter().all(|c| c.is_finite())));
    let mean: f32 = exr.pixels().map(|p| p.0[1]).sum::<f32>() / (48.0 * 32.0);
    assert!(mean > 0.01, "the Cornell box is lit: mean green {mean}");

    // Built-in scenes, health, metrics.
    let (status, scenes) = get(&s, &s.admin, "/api/scenes");
    assert_eq!(status, 200);
    let names: Vec<&str> = scenes["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["name"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"cornell") && names.contains(&"knot"),
        "{names:?}"
    );
    let (status, scene) = get(&s, &s.admin, "/api/scenes/cornell");
    assert_eq!(
        (status, scene["camera"]["width"].as_u64()),
        (200, Some(384))
    );
    assert_eq!(get(&s, &s.admin, "/api/scenes/nope").0, 404);
    let health = client().get(s.url("/healthz")).send().unwrap();
    assert_eq!(health.status().as_u16(), 200);
    let metrics = metrics(&s);
    assert!(
        metrics.contains("photonbox_jobs{status=\"done\"} 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("photonbox_photon_map_cache_misses_total 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("route=\"/api/jobs\",status=\"202\"} 1"),
        "{metrics}"
    );
}

/// The effects a job simulates, and why, are in its stats; a job may switch effects off.
#[test]
fn jobs_report_their_effects_and_may_switch_them_off() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let mut body = small("cornell_mirror_glass");
    let on = run_to_done(&s, &s.admin, body.clone());
    body["params"]["effects"] = json!({"caustics": false});
    let off = run_to_done(&s, &s.admin, body);
    let stats = |id: i64| get(&s, &s.admin, &format!("/api/jobs/{id}")).1["stats"].clone();
    let (on, off) = (stats(on), stats(off));
    assert_eq!(on["effects"]["caustics"]["simulated"], true, "{on}");
    assert!(on["photons"]["caustic_emitted"].as_u64().unwrap() > 0);
    assert_eq!(off["effects"]["caustics"]["simulated"], false, "{off}");
    let reason = off["effects"]["caustics"]["reason"].as_str().unwrap();
    assert!(reason.contains("effects.caustics: false"), "{reason}");
    assert_eq!(off["photons"]["caustic_emitted"], 0);
    assert_eq!(off["effects"]["lights[0]"]["simulated"], true, "{off}");
    assert_eq!(off["effects"]["refraction"]["simulated"], true, "{off}");
}

#[test]
fn camera_only_change_reuses_the_photon_maps() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let first = run_to_done(&s, &s.admin, small("cornell_mirror_glass"));

    // The same scene uploaded with another camera, resolution, k, spp and exposure.
    let (_, mut scene) = get(&s, &s.admin, "/api/scenes/cornell_mirror_glass");
    scene["camera"]["position"] = json!([0.3, 1.2, 3.5]);
    scene["camera"]["fov"] = json!(45);
    let body = json!({
        "scene": scene,
        "params": {"integrator": "photon", "width": 40, "height": 40, "photons": 20000, "caustic_photons": 20000,
                   "spp": 2, "gather_rays": 0, "k": 10, "exposure": 1.0}
    });
    let second = run_to_done(&s, &s.admin, body);
    // Different photon counts: new maps.
    let mut third_body = small("cornell_mirror_glass");
    third_body["params"]["photons"] = json!(30000);
    let third = run_to_done(&s, &s.admin, third_body);

    let stats = |id: i64| get(&s, &s.admin, &format!("/api/jobs/{id}")).1["stats"].clone();
    let (a, b, c) = (stats(first), stats(second), stats(third));
    assert_eq!(a["cache"]["photon_maps"], "miss");
    assert_eq!(a["photons"]["traced_by_this_job"], 40000);
    assert_eq!(b["cache"]["photon_maps"], "hit", "{b}");
    assert_eq!(
        b["photons"]["traced_by_this_job"], 0,
        "no photon was traced"
    );
    assert_eq!(b["times"]["photon_trace"], 0.0);
    assert_eq!(b["times"]["build_maps"], 0.0);
    assert_eq!(b["photons"]["global_stored"], a["photons"]["global_stored"]);
    assert_eq!(b["params"]["width"], 40);
    assert_eq!(c["cache"]["photon_maps"], "miss");
    let metrics = metrics(&s);
    assert!(
        metrics.contains("photonbox_photon_map_cache_hits_total 1"),
        "{metrics}"
    );
    assert!(
        metrics.contains("photonbox_photon_map_cache_misses_total 2"),
        "{metrics}"
    );
}

#[test]
fn cancel_stops_a_running_render_and_a_queued_one() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let running = submit(&s, &s.admin, long());
    let queued = submit(&s, &s.admin, small("cornell"));
    wait_running(&s, &s.admin, running);
    let (_, q) = get(&s, &s.admin, &format!("/api/jobs/{queued}"));
    assert_eq!(q["status"], "queued", "one job per user at a time");
    assert_eq!(q["queue_position"], 0);

    let t0 = Instant::now();
    let (status, v) = delete(&s, &s.admin, running);
    let took = t0.elapsed().as_secs_f64();
    assert_eq!(
        (status, v["status"].as_str()),
        (200, Some("cancelled")),
        "{v}"
    );
    assert!(
        took < 1.0,
        "the render stopped within 1 s (took {took:.2} s)"
    );
    let evs = follow_to_end(&s, &s.admin, running);
    assert_eq!(evs.last().unwrap().name, "cancelled");
    assert_eq!(
        bytes(&s, &s.admin, &format!("/api/jobs/{running}/image.png")).0,
        404
    );

    // The queued job then runs; cancelling a finished job deletes it and its files.
    expect_done(&s, &s.admin, queued);
    assert!(dir.path().join(format!("results/{queued}.png")).exists());
    assert_eq!(delete(&s, &s.admin, queued).0, 204);
    assert_eq!(get(&s, &s.admin, &format!("/api/jobs/{queued}")).0, 404);
    assert!(!dir.path().join(format!("results/{queued}.png")).exists());
    let third = submit(&s, &s.admin, long());
    let fourth = submit(&s, &s.admin, small("cornell"));
    let (status, v) = delete(&s, &s.admin, fourth);
    assert_eq!((status, v["status"].as_str()), (200, Some("cancelled")));
    delete(&s, &s.admin, third);
}

#[test]
fn tokens_and_visibility() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let bob = s.add_user("bob");
    let carol = s.add_user("carol");
    assert_ne!(bob, carol);
    assert!(
        !std::fs::read_to_string(dir.path().join("photonbox.sqlite3"))
            .unwrap_or_default()
            .contains(&bob),
        "tokens are stored hashed"
    );

    // No token, a malformed header, a wrong token: 401 with a JSON body.
    let r = client().get(s.url("/api/jobs")).send().unwrap();
    let (status, v) = json_of(r);
    assert_eq!(status, 401);
    assert_eq!(v["path"], "header.Authorization");
    let r = client()
        .get(s.url("/api/jobs"))
        .header("Authorization", "Basic abc")
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    assert_eq!(get(&s, "not-a-token", "/api/jobs").0, 401);
    assert_eq!(get(&s, &bob, "/api/me").1["name"], "bob");

    let mut public = small("cornell");
    public["public"] = json!(true);
    let bobs_private = submit(&s, &bob, small("cornell"));
    let bobs_public = submit(&s, &bob, public);
    let carols = submit(&s, &carol, small("cornell"));
    for (tok, id) in [(&bob, bobs_private), (&bob, bobs_public), (&carol, carols)] {
        follow_to_end(&s, tok, id);
    }
    let ids = |token: &str| -> Vec<i64> {
        get(&s, token, "/api/jobs").1["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j["id"].as_i64().unwrap())
            .collect()
    };
    // Newest first; carol sees her job and bob's public one, never his private one.
    assert_eq!(ids(&carol), vec![carols, bobs_public]);
    assert_eq!(ids(&bob), vec![bobs_public, bobs_private]);
    assert_eq!(ids(&s.admin), vec![carols, bobs_public, bobs_private]);
    let path = format!("/api/jobs/{bobs_private}");
    assert_eq!(
        get(&s, &carol, &path).0,
        404,
        "another user's private job does not exist"
    );
    assert_eq!(bytes(&s, &carol, &format!("{path}/image.png")).0, 404);
    assert_eq!(bytes(&s, &carol, &format!("{path}/events")).0, 404);
    assert_eq!(delete(&s, &carol, bobs_private).0, 404);
    assert_eq!(get(&s, &carol, &format!("/api/jobs/{bobs_public}")).0, 200);
    assert_eq!(
        bytes(&s, &carol, &format!("/api/jobs/{bobs_public}/image.png")).0,
        200
    );
    assert_eq!(
        delete(&s, &carol, bobs_public).0,
        403,
        "public jobs are read-only"
    );
    // The admin sees and may delete everything.
    assert_eq!(get(&s, &s.admin, &path).0, 200);
    assert_eq!(delete(&s, &s.admin, bobs_private).0, 204);
    assert_eq!(get(&s, &bob, &path).0, 404);
}

#[test]
fn limits_and_bad_input_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        dir.path(),
        &[
            "--max-body",
            "20000",
            "--max-queued",
            "2",
            "--max-pixels",
            "150000",
            "--memory-mb",
            "4096",
        ],
    );
    let t = &s.admin;
    let raw = |body: &str| {
        json_of(
            client()
                .post(s.url("/api/jobs"))
                .bearer_auth(t)
                .header("content-type", "application/json")
                .body(body.to_string())
                .send()
                .unwrap(),
        )
    };
    let (status, v) = raw(&format!(
        "{{\"scene_name\": \"cornell\", \"pad\": \"{}\"}}",
        "x".repeat(30000)
    ));
    assert_eq!((status, v["path"].as_str()), (413, Some("body")), "{v}");
    let (status, v) = raw("{\"scene_name\": \"cornell\"");
    assert_eq!((status, v["path"].as_str()), (400, Some("body")), "{v}");
    let with_params = |p: Value| json!({"scene_name": "cornell", "params": p});
    let cases = [
        (
            with_params(json!({"width": 400, "height": 400})),
            "params.width",
        ),
        (with_params(json!({"k": "many"})), "params.k"),
        (with_params(json!({"k": 0})), "params.k"),
        (with_params(json!({"photns": 5})), "params.photns"),
        (
            with_params(json!({"effects": {"shadows": false}})),
            "params.effects.shadows",
        ),
        (
            with_params(json!({"effects": {"caustics": "no"}})),
            "params.effects.caustics",
        ),
        (
            with_params(json!({"integrator": "magic"})),
            "params.integrator",
        ),
        (with_params(json!({"photons": 60000000})), "params.photons"),
        (
            with_params(json!({"integrator": "photon", "photons": 40000000})),
            "params",
        ),
        // The default integrator (auto) traces no photon maps.
        (with_params(json!({"photons": 1000})), "params.photons"),
        (json!({"scene_name": "nope"}), "scene_name"),
        (json!({}), "scene"),
        (json!({"scene_name": "cornell", "colour": 1}), "colour"),
        (json!({"scene": {"camera": 5}}), "scene.camera"),
    ];
    for (body, path) in cases {
        let (status, v) = post(&s, t, &body);
        assert_eq!(status, 422, "{body} -> {v}");
        assert_eq!(v["path"], path, "{body} -> {v}");
        assert!(v["error"].as_str().is_some_and(|e| !e.is_empty()));
    }
    let (_, v) = post(
        &s,
        t,
        &json!({"scene_name": "cornell", "params": {"integrator": "photon", "photons": 40000000}}),
    );
    assert!(
        v["error"].as_str().unwrap().contains("MiB"),
        "the estimate is given: {v}"
    );
    let (_, mut scene) = get(&s, t, "/api/scenes/cornell");
    scene["objects"][0]["corner"] = json!([0, "zero", 0]);
    let (status, v) = post(&s, t, &json!({"scene": scene}));
    assert_eq!(
        (status, v["path"].as_str()),
        (422, Some("scene.objects[0].corner[1]")),
        "{v}"
    );

    // Two queued jobs per user at most: the third waiting one is refused with 429.
    let long_job = json!({"scene_name": "cornell_mirror_glass",
        "params": {"integrator": "photon", "width": 64, "height": 64, "photons": 10000000, "caustic_photons": 1000, "spp": 1, "gather_rays": 0}});
    let running = submit(&s, t, long_job.clone());
    wait_running(&s, t, running);
    let q1 = submit(&s, t, small("cornell"));
    let q2 = submit(&s, t, small("cornell"));
    let (status, v) = post(&s, t, &small("cornell"));
    assert_eq!(
        (status, v["path"].as_str()),
        (429, Some("limits.max_queued_per_user")),
        "{v}"
    );
    for id in [q1, q2, running] {
        delete(&s, t, id);
    }
}

#[test]
fn nothing_is_lost_when_the_server_is_killed() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &["--max-running", "1"]);
    let t = s.admin.clone();
    let done = submit(&s, &t, small("cornell"));
    follow_to_end(&s, &t, done);
    let (_, png_before) = bytes(&s, &t, &format!("/api/jobs/{done}/image.png"));
    let mut medium = small("cornell_mirror_glass");
    medium["params"]["photons"] = json!(6000000);
    let running = submit(&s, &t, medium);
    let queued = submit(&s, &t, small("glass_orange"));
    wait_running(&s, &t, running);
    s.kill();

    let s = Server::start(dir.path(), &["--max-running", "1"]);
    assert_eq!(s.admin, t, "the admin token survives");
    let (status, job) = get(&s, &t, &format!("/api/jobs/{done}"));
    assert_eq!((status, job["status"].as_str()), (200, Some("done")));
    assert_eq!(
        bytes(&s, &t, &format!("/api/jobs/{done}/image.png")),
        (200, png_before)
    );
    // The interrupted job runs again, and the queued one runs.
    for id in [running, queued] {
        expect_done(&s, &t, id);
        assert_eq!(bytes(&s, &t, &format!("/api/jobs/{id}/image.exr")).0, 200);
    }
    let (_, list) = get(&s, &t, "/api/jobs");
    assert_eq!(list["jobs"].as_array().unwrap().len(), 3);
}

#[test]
fn a_small_job_is_not_stuck_behind_another_users_long_one() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let alice = s.add_user("alice");
    let bob = s.add_user("bob");
    let long_id = submit(&s, &alice, long());
    wait_running(&s, &alice, long_id);
    let t0 = Instant::now();
    let quick = json!({"scene_name": "cornell",
        "params": {"integrator": "raytrace", "width": 48, "height": 32, "spp": 1}});
    let small_id = submit(&s, &bob, quick);
    expect_done(&s, &bob, small_id);
    let took = t0.elapsed().as_secs_f64();
    let (_, long_job) = get(&s, &alice, &format!("/api/jobs/{long_id}"));
    assert_eq!(
        long_job["status"], "running",
        "bob's job finished ({took:.2} s) while alice's long one still runs"
    );
    delete(&s, &alice, long_id);
}

#[test]
fn sigterm_ends_streams_and_requeues_the_running_job() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let t = s.admin.clone();
    let id = submit(&s, &t, long());
    wait_running(&s, &t, id);
    // Connected (headers received) before the signal; read to the end in a thread: the
    // server must close the stream when it shuts down.
    let events = client()
        .get(s.url(&format!("/api/jobs/{id}/events")))
        .bearer_auth(&t)
        .send()
        .unwrap();
    assert_eq!(events.status().as_u16(), 200);
    let stream = std::thread::spawn(move || {
        let text = events.text().unwrap_or_default();
        text.lines().filter(|l| l.starts_with("event: ")).count()
    });
    let (status, took) = s.terminate();
    assert!(status.success(), "clean exit: {status:?}");
    assert!(took < 5.0, "exited within seconds (took {took:.2} s)");
    assert!(
        stream.join().unwrap() >= 1,
        "the event stream ended cleanly"
    );

    let s = Server::start(dir.path(), &[]);
    let (_, job) = get(&s, &t, &format!("/api/jobs/{id}"));
    assert!(
        job["status"] == "queued" || job["status"] == "running",
        "the interrupted job runs again: {job}"
    );
    delete(&s, &t, id);
}

/// An `auto` job that mirror or glass and a short time limit make one photon render reports
/// that render's phases as it goes (it reports no passes: counted by passes, it read next to
/// nothing until it was done).
#[test]
fn an_auto_job_made_one_photon_render_reports_its_progress() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let params = json!({"integrator": "auto", "width": 64, "height": 64, "time_limit": 4});
    let body = json!({"scene_name": "cornell_mirror_glass", "params": params});
    let id = submit(&s, &s.admin, body);
    let evs = follow_to_end(&s, &s.admin, id);
    let before_done: Vec<f64> = evs
        .iter()
        .filter(|e| e.name == "progress" && e.data["status"] == "running")
        .map(|e| e.data["progress"].as_f64().unwrap())
        .collect();
    let most = before_done.iter().copied().fold(0.0, f64::max);
    assert!(most > 0.3, "progress while running: {before_done:?}");
    let (_, job) = get(&s, &s.admin, &format!("/api/jobs/{id}"));
    let how = &job["stats"]["effects"]["integrator"]["how"];
    assert_eq!(how, "auto chose photon", "{job}");
}

/// A progressive job: a preview after each pass, then the final image; killed after some
/// passes, it resumes from its saved state and ends with the same bytes as a job that was
/// never interrupted (issue 4, on the server).
#[test]
fn ppm_jobs_stream_previews_and_resume_after_a_crash() {
    let (_dir, s) = progressive_job_resumes_after_a_crash(json!({"integrator": "ppm",
        "iterations": 40, "width": 64, "height": 48, "photons": 60000,
        "caustic_photons": 60000}));
    let t = s.admin.clone();
    // ppm-only parameters elsewhere, and out-of-range ones, name their field.
    let (status, err) = post(
        &s,
        &t,
        &json!({"scene_name": "cornell", "params": {"integrator": "photon", "iterations": 4}}),
    );
    assert_eq!(
        (status, err["path"].as_str()),
        (422, Some("params.iterations"))
    );
    let (status, err) = post(
        &s,
        &t,
        &json!({"scene_name": "cornell", "params": {"integrator": "ppm", "alpha": 1.5}}),
    );
    assert_eq!((status, err["path"].as_str()), (422, Some("params.alpha")));
}

/// The vcm job of [`ppm_jobs_stream_previews_and_resume_after_a_crash`]: every progressive
/// integrator resumes through the same state.
#[test]
fn vcm_jobs_stream_previews_and_resume_after_a_crash() {
    progressive_job_resumes_after_a_crash(json!({"integrator": "vcm", "iterations": 40,
        "width": 64, "height": 48}));
}

/// Submit a progressive job, kill the server after a few previews, restart it: the job
/// resumes from its saved state and ends with the bytes of a job never interrupted. Returns
/// the restarted server (and its data folder, which outlives it).
fn progressive_job_resumes_after_a_crash(params: Value) -> (tempfile::TempDir, Server) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let s = Server::start(&dir, &["--max-running", "1"]);
    let t = s.admin.clone();
    let passes = params["iterations"].as_u64().unwrap();
    let job = json!({"scene_name": "cornell_mirror_glass", "params": params});
    let id = submit(&s, &t, job.clone());
    // Passes are published as previews; wait for a few, then kill the server mid-render.
    let evs = follow(&s, &t, id, |e| {
        e.data["previews"].as_u64().unwrap_or(0) >= 3
    });
    let last = evs.last().unwrap();
    assert_eq!(last.data["status"], "running", "{evs:?}");
    assert!(evs.iter().any(|e| e.name == "preview"), "{evs:?}");
    let (status, png) = bytes(&s, &t, &format!("/api/jobs/{id}/image.png"));
    assert_eq!(status, 200, "a preview image is served while the job runs");
    assert!(png.starts_with(b"\x89PNG"));
    s.kill();
    let state = dir.join("results").join(format!("{id}.ppmstate"));
    assert!(state.is_file());

    let s = Server::start(&dir, &["--max-running", "1"]);
    expect_done(&s, &t, id);
    let (_, resumed) = get(&s, &t, &format!("/api/jobs/{id}"));
    let history = resumed["stats"]["ppm"]["history"].as_array().unwrap();
    assert_eq!(history.len() as u64, passes, "every pass is in the stats");
    let from = resumed["stats"]["ppm_state"]["resumed_from_pass"].as_u64();
    assert!(from.is_some_and(|n| n >= 3), "{}", resumed["stats"]);
    assert_eq!(resumed["stats"]["ppm"]["passes"], passes);
    assert_eq!(
        resumed["stats"]["params"]["integrator"],
        job["params"]["integrator"]
    );
    assert!(!state.exists());

    let again = submit(&s, &t, job);
    follow_to_end(&s, &t, again);
    let (_, a) = bytes(&s, &t, &format!("/api/jobs/{id}/image.exr"));
    let (_, b) = bytes(&s, &t, &format!("/api/jobs/{again}/image.exr"));
    assert!(
        a == b,
        "the resumed job's EXR differs from an uninterrupted one"
    );
    (tmp, s)
}

/// With one render slot, a progressive job gives way to another user's job between two
/// passes, then resumes from its saved state and still ends with every pass.
#[test]
fn a_progressive_job_yields_its_slot_between_passes() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &["--max-running", "1"]);
    let alice = s.add_user("alice");
    let bob = s.add_user("bob");
    let job = json!({
        "scene_name": "cornell",
        "params": {"integrator": "ppm", "iterations": 400, "width": 32, "height": 32,
                   "photons": 20000}
    });
    let long_id = submit(&s, &alice, job);
    wait_running(&s, &alice, long_id);
    let quick = json!({"scene_name": "cornell",
        "params": {"integrator": "raytrace", "width": 48, "height": 32, "spp": 1}});
    let small_id = submit(&s, &bob, quick);
    expect_done(&s, &bob, small_id);
    let (_, long_job) = get(&s, &alice, &format!("/api/jobs/{long_id}"));
    assert_ne!(
        long_job["status"], "done",
        "bob's job ran while alice's 400 passes were not done"
    );
    expect_done(&s, &alice, long_id);
    let (_, long_job) = get(&s, &alice, &format!("/api/jobs/{long_id}"));
    assert_eq!(long_job["stats"]["ppm"]["passes"], 400);
    assert_eq!(long_job["stats"]["ppm"]["stopped_by"], "iterations");
}

#[test]
fn the_gallery_page_is_served_from_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    assert_eq!(s.sign_in, format!("{}/?token={}", s.base, s.admin));
    // The page and its files need no token; they hold no data.
    let r = client().get(&s.sign_in).send().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    let csp = r.headers()["content-security-policy"].to_str().unwrap();
    assert!(
        csp.starts_with("default-src 'self'; img-src 'self' blob:"),
        "{csp}"
    );
    let html = r.text().unwrap();
    // The script is a native ES module (no build step); it imports the others.
    assert!(html.contains(r#"<script type="module" src="/web/app.js"></script>"#));
    let js = "text/javascript; charset=utf-8";
    for (path, mime, needle) in [
        ("/web/app.js", js, "function route"),
        ("/web/api.js", js, "function followEvents"),
        ("/web/state.js", js, "export const state"),
        ("/web/format.js", js, "function fmtSeconds"),
        ("/web/gallery.js", js, "function refreshGallery"),
        ("/web/submit.js", js, "function estimateSeconds"),
        ("/web/job.js", js, "function openJob"),
        ("/web/charts.js", js, "function logChart"),
        ("/web/compare.js", js, "function openCompare"),
        (
            "/web/style.css",
            "text/css; charset=utf-8",
            ".gallery-layout",
        ),
    ] {
        let r = client().get(s.url(path)).send().unwrap();
        assert_eq!(r.status().as_u16(), 200, "{path}");
        assert_eq!(r.headers()["content-type"], mime, "{path}");
        assert!(r.text().unwrap().contains(needle), "{path}");
    }
    // Every module app.js reaches through its imports is served as JavaScript, and each
    // module above is reached: the embedded table and the imports agree.
    let mut reached = vec!["app.js".to_string()];
    let mut next = 0;
    while let Some(file) = reached.get(next).cloned() {
        next += 1;
        let r = client().get(s.url(&format!("/web/{file}"))).send().unwrap();
        assert_eq!(r.status().as_u16(), 200, "{file}");
        assert_eq!(r.headers()["content-type"], js, "{file}");
        let text = r.text().unwrap();
        for import in text.split(r#" from "./"#).skip(1) {
            let name = &import[..import.find('"').unwrap()];
            if !reached.iter().any(|f| f == name) {
                reached.push(name.to_string());
            }
        }
    }
    reached.sort();
    assert_eq!(
        reached,
        [
            "api.js",
            "app.js",
            "charts.js",
            "compare.js",
            "format.js",
            "gallery.js",
            "job.js",
            "state.js",
            "submit.js"
        ]
    );
    // Only the embedded files: nothing else under /web, and no way out of it.
    for path in ["/web/index.htm", "/web/..%2FCargo.toml", "/web/"] {
        let (status, v) = json_of(client().get(s.url(path)).send().unwrap());
        assert_eq!(status, 404, "{path}: {v}");
    }
}

/// A job measured against a finished reference job: a ppm job's stats carry the error of
/// every pass, a photon job's its final error; a reference that is unknown, another
/// user's private job, not done or of another size is refused by name; one deleted before
/// the job runs fails the job with a clear error.
#[test]
fn jobs_are_measured_against_a_reference_job() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let t = s.admin.clone();
    let ppm = |iterations: u32, photons: u32, seed: u32| {
        json!({
            "scene_name": "cornell",
            "params": {"integrator": "ppm", "iterations": iterations, "width": 48,
                       "height": 32, "photons": photons, "caustic_photons": photons,
                       "seed": seed}
        })
    };
    let reference = run_to_done(&s, &t, ppm(24, 40000, 7));

    let mut measured = ppm(8, 10000, 1);
    measured["params"]["reference_job"] = json!(reference);
    let id = run_to_done(&s, &t, measured);
    let (_, job) = get(&s, &t, &format!("/api/jobs/{id}"));
    assert_eq!(job["params"]["reference_job"], reference);
    let history = job["stats"]["ppm"]["history"].as_array().unwrap();
    assert_eq!(history.len(), 8);
    let relmse: Vec<f64> = history
        .iter()
        .map(|h| h["error"]["relmse"].as_f64().unwrap())
        .collect();
    assert!(
        relmse.iter().all(|e| e.is_finite() && *e > 0.0),
        "{relmse:?}"
    );
    assert!(
        relmse[7] < relmse[0],
        "the error falls over the passes: {relmse:?}"
    );
    assert!(history.iter().all(|h| h["error"]["block_err"].is_f64()));
    assert_eq!(job["stats"]["error"]["relmse"].as_f64(), Some(relmse[7]));

    let mut photon = small("cornell");
    photon["params"]["reference_job"] = json!(reference);
    let id = run_to_done(&s, &t, photon.clone());
    let (_, job) = get(&s, &t, &format!("/api/jobs/{id}"));
    let e = &job["stats"]["error"];
    assert!(e["relmse"].as_f64().unwrap().is_finite(), "{e}");
    let ratio = e["mean_ratio"].as_f64().unwrap();
    assert!((0.5..2.0).contains(&ratio), "{e}");

    // Refused: unknown, another user's private job, not done, another size.
    let bob = s.add_user("bob");
    let refused = |token: &str, body: &Value, why: &str| {
        let (status, v) = post(&s, token, body);
        assert_eq!(
            (status, v["path"].as_str()),
            (422, Some("params.reference_job")),
            "{why}: {v}"
        );
        assert!(!v["error"].as_str().unwrap_or("").is_empty(), "{v}");
        v
    };
    let with_ref = |body: &Value, r: i64| {
        let mut b = body.clone();
        b["params"]["reference_job"] = json!(r);
        b
    };
    refused(&t, &with_ref(&photon, 999_999), "unknown");
    refused(
        &bob,
        &with_ref(&photon, reference),
        "another user's private job",
    );
    let mut other_size = with_ref(&photon, reference);
    other_size["params"]["width"] = json!(40);
    let v = refused(&t, &other_size, "another size");
    assert!(v["error"].as_str().unwrap().contains("48x32"), "{v}");
    let running = submit(&s, &t, long());
    refused(&t, &with_ref(&long(), running), "not done");

    // The reference is deleted while the job waits (behind this user's running job).
    let waiting = submit(&s, &t, with_ref(&photon, reference));
    assert_eq!(delete(&s, &t, reference).0, 204);
    delete(&s, &t, running);
    let evs = follow_to_end(&s, &t, waiting);
    assert_eq!(evs.last().unwrap().name, "failed", "{evs:?}");
    let (_, job) = get(&s, &t, &format!("/api/jobs/{waiting}"));
    let error = job["error"].as_str().unwrap();
    assert!(
        error.contains(&format!("reference job {reference}")),
        "{error}"
    );
}
