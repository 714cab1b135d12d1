//! A user's limits on the farm as on one box: the storage quota (on both stores, `both!`),
//! and the queued-job limit held under concurrent submissions.

use std::sync::Barrier;

use serde_json::{Value, json};

use crate::both;
use crate::harness::*;

/// Uploaded scenes of 600 kB, two of which do not fit a quota of 1 MiB; another user has a
/// quota of their own; deleting frees the space.
fn a_user_storage_quota_refuses_new_jobs_until_old_ones_are_deleted(kind: Kind) {
    let d = Deployment::start_with(kind, 1, &["--storage-mb", "1"]);
    let (api, admin) = (&d.api, &d.admin);
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell.json"))
        .unwrap();
    let mut scene: Value = serde_json::from_str(&text).unwrap();
    scene["description"] = json!("x".repeat(600_000));
    let job = json!({"scene": scene, "params": {"width": 8, "height": 8,
        "spp": 1, "integrator": "raytrace"}});
    let run_to_done = |token: &str| {
        let (status, v) = api.post_job(token, &job);
        assert_eq!(status, 202, "{v}");
        let id = v["id"].as_i64().unwrap();
        api.wait_done(token, id);
        id
    };
    let first = run_to_done(admin);
    let (status, v) = api.post_job(admin, &job);
    assert_eq!(
        (status, &v["path"]),
        (422, &json!("limits.storage_per_user")),
        "{v}"
    );
    let bob = d.add_user("bob");
    run_to_done(&bob);
    assert_eq!(api.delete_job(admin, first), 204);
    run_to_done(admin);
}
both!(a_user_storage_quota_refuses_new_jobs_until_old_ones_are_deleted);

/// Submissions racing each other cannot pass the queued-job limit together: each is checked
/// in its own transaction under a lock on its user's row. No worker, so nothing leaves the
/// queue.
#[test]
fn concurrent_submissions_do_not_pass_the_queued_limit() {
    let d = Deployment::start_with(Kind::Postgres, 0, &["--max-queued", "2"]);
    let (api, admin) = (&d.api, &d.admin);
    let n = 8;
    let barrier = Barrier::new(n);
    let statuses: Vec<u16> = std::thread::scope(|s| {
        let racers: Vec<_> = (0..n)
            .map(|_| {
                s.spawn(|| {
                    let body = json!({"scene_name": "cornell", "params": ppm_params()});
                    barrier.wait();
                    api.post_job(admin, &body).0
                })
            })
            .collect();
        racers.into_iter().map(|r| r.join().unwrap()).collect()
    });
    let accepted = statuses.iter().filter(|&&s| s == 202).count();
    let refused = statuses.iter().filter(|&&s| s == 429).count();
    assert_eq!((accepted, refused), (2, n - 2), "{statuses:?}");
    let jobs: Value = serde_json::from_slice(&api.get(admin, "/api/jobs").1).unwrap();
    assert_eq!(jobs["jobs"].as_array().unwrap().len(), 2);
}
