//! Previews of a farm job while it runs (`farm::preview`): the image URLs of a running job
//! serve the mean of the passes its done tasks rendered, the same bytes as `photonbox
//! render` of that many passes.

use std::time::{Duration, Instant};

use serde_json::json;

use crate::harness::*;

#[test]
fn a_running_job_previews_the_passes_done_at_the_bytes_of_a_shorter_render() {
    let store = fresh_store();
    let (api, admin) = start_api(&store);
    let admin = admin.unwrap();
    // 16 passes of one task each.
    let id = api.submit(&admin, slow_ppm_params());
    let exr_path = format!("/api/jobs/{id}/image.exr");
    assert_eq!(
        api.get(&admin, &exr_path).0,
        404,
        "a preview before any task"
    );
    // One worker (tasks done in order: the passes done are 1..=d), a lease that outlasts
    // the pause below.
    let worker = start_worker(&store, "only", 600.0);
    let t0 = Instant::now();
    while api.job(&admin, id)["progress"].as_f64().unwrap() < 0.2 {
        assert!(t0.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(50));
    }
    // Stopped, the worker leaves the job running with some tasks done; read the count on
    // both sides of the preview (a result it handed in just before the stop may land
    // meanwhile).
    worker.signal(libc::SIGSTOP);
    let done = |api: &Api| {
        let job = api.job(&admin, id);
        assert_eq!(job["status"], "running", "{job}");
        (job["progress"].as_f64().unwrap() * 16.0).round() as u32
    };
    let (passes, preview) = loop {
        let before = done(&api);
        let (status, bytes) = api.get(&admin, &exr_path);
        assert_eq!(status, 200);
        if done(&api) == before {
            break (before, bytes);
        }
    };
    assert!((3..16).contains(&passes), "{passes} passes");
    let mut shorter = slow_ppm_params();
    shorter["iterations"] = json!(passes);
    assert!(
        preview == render_one_box(&shorter),
        "the preview is not the image of passes 1-{passes}"
    );
    let png = client()
        .get(format!("{}/api/jobs/{id}/image.png", api.base))
        .bearer_auth(&admin)
        .send()
        .unwrap();
    assert_eq!(png.status().as_u16(), 200);
    assert_eq!(png.headers()["content-type"], "image/png");
    assert_eq!(png.headers()["cache-control"], "no-store");
    assert!(png.bytes().unwrap().starts_with(b"\x89PNG"));
    worker.signal(libc::SIGCONT);
    assert!(api.wait_done(&admin, id) == slow_one_box_exr());
}
