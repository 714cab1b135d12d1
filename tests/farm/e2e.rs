//! The farm as processes: one `photonbox serve --store postgres://... --no-render` and
//! `photonbox worker` processes against a real PostgreSQL, driven over HTTP as a user
//! would; the job's image compared with `photonbox render` of the same spec on one box,
//! byte for byte. The tests that apply to one box too run again on `photonbox serve` with
//! the embedded SQLite store (`both!`), so that the two stores cannot drift apart.

use std::time::{Duration, Instant};

use serde_json::json;

use crate::both;
use crate::harness::*;
use crate::pg::Cluster;

/// A job of `params` rendered by a deployment of three workers: the deployment, the job's
/// id and its served EXR (on PostgreSQL, checked to be spread over at least two workers).
fn on_three_workers(kind: Kind, params: serde_json::Value) -> (Deployment, i64, Vec<u8>) {
    let d = Deployment::start(kind, 3);
    let id = d.api.submit(&d.admin, params);
    let served = d.api.wait_done(&d.admin, id);
    if let Kind::Postgres = kind {
        assert!(workers_of(d.store(), id) >= 2, "the tasks were not spread");
    }
    (d, id, served)
}

fn a_job_spread_over_three_workers_is_the_bytes_of_one_box(kind: Kind) {
    let (d, id, served) = on_three_workers(kind, ppm_params());
    let (api, admin) = (&d.api, &d.admin);
    if let Kind::Postgres = kind {
        let job = api.job(admin, id);
        assert_eq!(job["stats"]["farm"]["tasks"], 16, "{job}");
        // GET /api/workers counts each worker's accepted results.
        let (status, body) = api.get(admin, "/api/workers");
        assert_eq!(status, 200);
        let workers: serde_json::Value = serde_json::from_slice(&body).unwrap();
        let done = workers["workers"].as_array().unwrap().iter();
        let done: Vec<i64> = done.map(|w| w["tasks_done"].as_i64().unwrap()).collect();
        assert_eq!(done.iter().sum::<i64>(), 16, "{workers}");
        assert!(done.iter().filter(|&&n| n > 0).count() >= 2, "{workers}");
    }
    assert!(
        served == one_box_exr(),
        "the served EXR differs from photonbox render's"
    );
}
both!(a_job_spread_over_three_workers_is_the_bytes_of_one_box);

fn a_one_shot_job_in_bands_over_three_workers_is_the_bytes_of_one_box(kind: Kind) {
    let (d, id, served) = on_three_workers(kind, photon_params());
    if let Kind::Postgres = kind {
        let job = d.api.job(&d.admin, id);
        let tasks = job["stats"]["farm"]["tasks"].as_i64().unwrap();
        assert!(tasks >= 8, "{job}");
    }
    assert!(
        served == render_one_box(&photon_params()),
        "the served EXR differs from photonbox render's"
    );
}
both!(a_one_shot_job_in_bands_over_three_workers_is_the_bytes_of_one_box);

#[test]
fn a_worker_killed_mid_task_loses_it_to_another_and_the_bytes_hold() {
    let store = fresh_store();
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    let victim = start_worker(&store, "victim", 1.0);
    let id = api.submit(&admin, slow_ppm_params());
    // As soon as the victim holds a task, SIGKILL it.
    let url = store.clone();
    store_query(&url, async move |pool| {
        await_lease(pool, "victim").await;
    });
    victim.signal(libc::SIGKILL);
    drop(victim);
    let _others: Vec<Proc> = (0..2)
        .map(|i| start_worker(&store, &format!("w{i}"), 10.0))
        .collect();
    let farm = api.wait_done(&admin, id);
    assert!(api.metric("photonbox_farm_store_leases_expired_total") >= 1);
    assert!(
        farm == slow_one_box_exr(),
        "after a lost worker the EXR differs"
    );
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
    // A short lease: heartbeats every 0.1 s, in tasks of about a second.
    let _cut = start_worker(&cut_url, "cut", 0.3);
    let params = long_task_ppm_params();
    let id = api.submit(&admin, params.clone());
    store_query(&store, async move |pool| {
        // Rendering, not still reading the job (cut off then, it would have no result).
        await_heartbeat(pool, "cut").await;
        // Cut it off: no new logins, its connections terminated.
        sqlx::raw_sql(
            "ALTER ROLE cut NOLOGIN;
             SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE usename = 'cut';",
        )
        .execute(pool)
        .await
        .unwrap();
    });
    // It was cut off mid-task: the task it holds is still leased to it, not done.
    store_query(&store, async |pool| {
        let held: i64 = sqlx::query_scalar(
            "SELECT count(*) FROM tasks WHERE worker = 'cut' AND state = 'leased'",
        )
        .fetch_one(pool)
        .await
        .unwrap();
        assert_eq!(
            held, 1,
            "the cut-off worker finished its task before the cut"
        );
    });
    // Another worker finishes the job, the cut-off worker's task included.
    let _other = start_worker(&store, "other", 10.0);
    let farm = api.wait_done(&admin, id);
    assert!(farm == render_one_box(&params));
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

/// `slow_ppm_params` in 4 tasks of about a second each (one pass each, 4x the photons).
fn long_task_ppm_params() -> serde_json::Value {
    let mut params = slow_ppm_params();
    params["photons"] = json!(1_200_000);
    params["caustic_photons"] = json!(1_200_000);
    params["iterations"] = json!(4);
    params
}

/// Wait (at most a minute) until worker `worker` has extended a lease it holds: it sends
/// heartbeats only while it renders the task.
async fn await_heartbeat(pool: &sqlx::PgPool, worker: &str) {
    let lease_until = async || -> Option<f64> {
        sqlx::query_scalar(
            "SELECT extract(epoch FROM lease_until)::float8 FROM tasks
              WHERE worker = $1 AND state = 'leased'",
        )
        .bind(worker)
        .fetch_optional(pool)
        .await
        .unwrap()
    };
    await_lease(pool, worker).await;
    let first = lease_until().await;
    let t0 = Instant::now();
    loop {
        match lease_until().await {
            Some(t) if Some(t) != first => return,
            None => panic!("{worker}'s task ended before a heartbeat (too short a task?)"),
            Some(_) => {}
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "{worker} never extended its lease {first:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

fn a_cancel_reaches_the_worker_within_a_second(kind: Kind) {
    let d = Deployment::start(kind, 1);
    let (api, admin) = (&d.api, &d.admin);
    // One long task: a ppm job that stops by time renders whole on one worker.
    let mut params = ppm_params();
    params["iterations"] = json!(100000);
    params["time_limit"] = json!(600);
    let id = api.submit(admin, params);
    api.wait(admin, id, Duration::from_secs(60), |j| {
        j["status"] == "running"
    });
    assert_eq!(api.delete_job(admin, id), 200);
    let t0 = Instant::now();
    // The render has stopped when its worker (its box) starts the user's next job.
    let next = api.submit(
        admin,
        json!({"integrator": "raytrace", "spp": 1, "width": 8, "height": 8}),
    );
    api.wait(admin, next, Duration::from_secs(1), |j| {
        j["status"] != "queued"
    });
    assert!(
        t0.elapsed() < Duration::from_secs(1),
        "the cancel took {:?}",
        t0.elapsed()
    );
    assert_eq!(api.job(admin, id)["status"], "cancelled");
}
both!(a_cancel_reaches_the_worker_within_a_second);

/// A split job's cancel reaches every worker rendering a piece of it: the three are all
/// free for other work within a second (each takes one of three long jobs submitted
/// after the cancel, so all three are running only once every worker has stopped).
#[test]
fn a_cancel_reaches_every_worker_of_a_split_job_within_a_second() {
    let d = Deployment::start(Kind::Postgres, 3);
    let (api, admin) = (&d.api, &d.admin);
    // Pieces of one pass that take seconds each on one thread.
    let mut params = slow_ppm_params();
    params["photons"] = json!(3_000_000);
    params["caustic_photons"] = json!(3_000_000);
    let id = api.submit(admin, params);
    store_query(d.store(), async |pool| {
        for w in ["w0", "w1", "w2"] {
            await_lease(pool, w).await;
        }
    });
    assert_eq!(api.delete_job(admin, id), 200);
    let t0 = Instant::now();
    let mut long = ppm_params();
    long["iterations"] = json!(100000);
    long["time_limit"] = json!(600);
    let next: Vec<i64> = (0..3).map(|_| api.submit(admin, long.clone())).collect();
    for &n in &next {
        api.wait(admin, n, Duration::from_secs(1), |j| {
            j["status"] == "running"
        });
    }
    assert!(
        t0.elapsed() < Duration::from_secs(1),
        "the three workers were free after {:?}",
        t0.elapsed()
    );
    assert_eq!(api.job(admin, id)["status"], "cancelled");
}

fn an_acknowledged_job_survives_the_api_killed_and_the_store_restarted(kind: Kind) {
    let mut d = Deployment::start(kind, 1);
    // Acknowledged (202), then the API (on one box, the server) SIGKILLed and the store's
    // server restarted.
    let id = d.api.submit(&d.admin, ppm_params());
    d.crash_and_restart();
    let served = d.api.wait_done(&d.admin, id);
    assert!(served == one_box_exr());
}
both!(an_acknowledged_job_survives_the_api_killed_and_the_store_restarted);

fn a_small_job_behind_another_user_s_long_one_starts_at_once(kind: Kind) {
    let d = Deployment::start(kind, 3);
    let (api, admin) = (&d.api, &d.admin);
    let bob = d.add_user("bob");
    let long = json!({"integrator": "ppm", "photons": 20000, "caustic_photons": 20000,
                      "iterations": 96, "width": 64, "height": 48});
    let long = api.submit(admin, long);
    api.wait(admin, long, Duration::from_secs(60), |j| {
        j["status"] == "running"
    });
    let small = api.submit(
        &bob,
        json!({"integrator": "raytrace", "spp": 1, "width": 16, "height": 16}),
    );
    let job = api.wait(&bob, small, Duration::from_secs(120), |j| {
        j["status"] == "done"
    });
    let behind = api.job(admin, long);
    assert_eq!(
        behind["status"], "running",
        "the small job waited for the long one"
    );
    // It started as soon as a worker finished the task it held (of the long job's 16),
    // and was done well before the long job was half done (FIFO over users: 0.75).
    assert!(
        behind["progress"].as_f64().unwrap() < 0.5,
        "{behind}, {job}"
    );
}
both!(a_small_job_behind_another_user_s_long_one_starts_at_once);

fn events_follow_a_job_to_its_end(kind: Kind) {
    let d = Deployment::start(kind, 2);
    let (api, admin) = (&d.api, &d.admin);
    let id = api.submit(admin, ppm_params());
    let resp = client()
        .get(format!("{}/api/jobs/{id}/events", api.base))
        .bearer_auth(admin)
        .send()
        .unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    // The stream ends after its final event: read it to the end.
    let text = resp.text().unwrap();
    let names: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("event: "))
        .collect();
    assert_eq!(names.first(), Some(&"status"), "{text}");
    assert!(names.contains(&"progress"), "{text}");
    assert_eq!(names.last(), Some(&"done"), "{text}");
    let progress: Vec<f64> = text
        .lines()
        .filter_map(|l| l.strip_prefix("data: "))
        .map(|d| {
            serde_json::from_str::<serde_json::Value>(d).unwrap()["progress"]
                .as_f64()
                .unwrap()
        })
        .collect();
    assert!(
        progress.windows(2).all(|w| w[0] <= w[1]),
        "progress went back: {progress:?}"
    );
    assert_eq!(progress.last(), Some(&1.0));
}
both!(events_follow_a_job_to_its_end);

fn a_private_job_is_seen_by_its_owner_and_the_admin_only(kind: Kind) {
    let d = Deployment::start(kind, 0);
    let (api, admin) = (&d.api, &d.admin);
    let (bob, carol) = (d.add_user("bob"), d.add_user("carol"));
    let id = api.submit(
        &bob,
        json!({"integrator": "raytrace", "spp": 1, "width": 8, "height": 8}),
    );
    let listed = |token: &str| -> bool {
        let (status, body) = api.get(token, "/api/jobs");
        assert_eq!(status, 200);
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        v["jobs"].as_array().unwrap().iter().any(|j| j["id"] == id)
    };
    assert!(listed(&bob) && listed(admin));
    assert!(!listed(&carol), "another user's private job is listed");
    assert_eq!(api.get(&carol, &format!("/api/jobs/{id}")).0, 404);
    assert_eq!(api.delete_job(&carol, id), 404);
    assert_eq!(api.get("not-a-token", "/api/jobs").0, 401);
    if let Kind::Postgres = kind {
        // The unauthenticated /metrics count bob's queued task (no worker takes it), and
        // do not say whose it is.
        assert_eq!(api.metric("photonbox_farm_queued_tasks"), 1);
        assert_eq!(api.metric("photonbox_farm_queued_users"), 1);
        let text = String::from_utf8(api.get("", "/metrics").1).unwrap();
        assert!(!text.contains("user=") && !text.contains("bob"), "{text}");
    }
}
both!(a_private_job_is_seen_by_its_owner_and_the_admin_only);

#[test]
fn a_worker_started_before_its_store_waits_for_it() {
    let own = Cluster::new(false);
    let store = fresh_store_of(&own);
    own.stop();
    // The store is down: the worker waits for it rather than exiting, and says so on its
    // health probe.
    let (mut worker, probes) = start_worker_with_probes(&store, "early");
    let probe = |path: &str| {
        let r = client().get(format!("{probes}{path}")).send().unwrap();
        (r.status().as_u16(), r.text().unwrap())
    };
    assert_eq!(probe("/healthz"), (503, "joining the farm\n".to_string()));
    own.start();
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    let id = api.submit(&admin, ppm_params());
    assert!(api.wait_done(&admin, id) == one_box_exr());
    assert!(worker.0.try_wait().unwrap().is_none(), "the worker exited");
    // Joined: healthy, and its own /metrics count the 16 tasks it claimed.
    assert_eq!(probe("/healthz"), (200, "ok\n".to_string()));
    let (status, metrics) = probe("/metrics");
    assert_eq!(status, 200);
    assert!(
        metrics.contains("\nphotonbox_farm_tasks_claimed_total 16\n"),
        "{metrics}"
    );
    // The store gone, its probes say so, and keep the store's error (its address, its
    // user) for the log.
    own.stop();
    assert_eq!(probe("/healthz"), (503, "store unavailable\n".to_string()));
}
