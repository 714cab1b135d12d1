//! The gallery on either store: the page, its scripts and the API it reads (scenes, the
//! spec's defaults, jobs in the one-box server's shape), and a finished job deleted. Run on
//! the farm and on one box (`both!`), so that a field the gallery reads cannot go missing
//! from either.

use serde_json::Value;

use crate::both;
use crate::harness::*;

/// The fields of a job as `GET /api/jobs/{id}` shows it (`server::views::JobView`).
const JOB_FIELDS: [&str; 18] = [
    "created",
    "error",
    "eta_seconds",
    "finished",
    "id",
    "links",
    "memory_estimate_bytes",
    "mine",
    "owner",
    "params",
    "phase",
    "progress",
    "public",
    "queue_position",
    "scene",
    "started",
    "stats",
    "status",
];

fn json(api: &Api, token: &str, path: &str) -> Value {
    let (status, body) = api.get(token, path);
    assert_eq!(status, 200, "{path}: {}", String::from_utf8_lossy(&body));
    serde_json::from_slice(&body).unwrap()
}

fn fields(job: &Value) -> Vec<&str> {
    let mut keys: Vec<&str> = job
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    keys.sort();
    keys
}

fn the_gallery_and_the_api_it_reads_are_served(kind: Kind) {
    let d = Deployment::start(kind, 1);
    let (api, admin) = (&d.api, &d.admin);

    let (status, page) = api.get("", "/");
    assert_eq!(status, 200);
    let page = String::from_utf8(page).unwrap();
    assert!(
        page.contains(r#"<script type="module" src="/web/app.js">"#),
        "{page}"
    );
    let (status, script) = api.get("", "/web/app.js");
    assert_eq!((status, script.is_empty()), (200, false));

    let doc = json(api, "", "/api/openapi.json");
    let defaults = &doc["components"]["schemas"]["Params"]["x-defaults"];
    assert!(defaults["ppm"].is_object(), "no ppm defaults: {defaults}");
    // The farm's document has its own route too.
    let farm_only = doc["paths"]["/api/workers"]["get"].is_object();
    assert_eq!(
        farm_only,
        matches!(kind, Kind::Postgres),
        "{}",
        doc["paths"]
    );
    let scenes = json(api, admin, "/api/scenes");
    let names: Vec<&str> = scenes["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"cornell_mirror_glass"), "{names:?}");
    assert!(json(api, admin, "/api/scenes/cornell")["camera"].is_object());
    assert_eq!(api.get(admin, "/api/scenes/nowhere").0, 404);
    assert_eq!(api.get("", "/api/scenes").0, 401);

    let id = api.submit(admin, ppm_params());
    api.wait_done(admin, id);
    let job = api.job(admin, id);
    assert_eq!(fields(&job), JOB_FIELDS, "{job}");
    assert_eq!(job["owner"], "admin");
    assert_eq!(job["mine"], true);
    assert_eq!(job["progress"], 1.0);
    assert_eq!(job["eta_seconds"], 0.0, "{job}");
    assert_eq!(job["links"]["png"], format!("/api/jobs/{id}/image.png"));
    assert_eq!(job["links"]["events"], format!("/api/jobs/{id}/events"));
    assert!(job["memory_estimate_bytes"].as_u64().unwrap() > 0, "{job}");
    if let Kind::Postgres = kind {
        // Merged, the tasks' results are dropped: a finished job keeps its images only.
        let kept: i64 = store_query(d.store(), async move |pool| {
            sqlx::query_scalar(
                "SELECT count(*) FROM tasks WHERE job_id = $1 AND result IS NOT NULL",
            )
            .bind(id)
            .fetch_one(pool)
            .await
            .unwrap()
        });
        assert_eq!(kept, 0, "task results kept after the merge");
    }
    let list = json(api, admin, "/api/jobs");
    let listed = &list["jobs"].as_array().unwrap()[0];
    assert_eq!(
        (listed["id"].as_i64(), fields(listed)),
        (Some(id), JOB_FIELDS.to_vec())
    );

    // A finished job deleted goes with its images.
    assert_eq!(api.delete_job(admin, id), 204);
    assert_eq!(api.get(admin, &format!("/api/jobs/{id}")).0, 404);
    assert_eq!(api.get(admin, &format!("/api/jobs/{id}/image.exr")).0, 404);
    assert!(
        json(api, admin, "/api/jobs")["jobs"]
            .as_array()
            .unwrap()
            .is_empty()
    );
}
both!(the_gallery_and_the_api_it_reads_are_served);

/// What is not a job id names no job, and two Authorization headers are refused even when
/// one of them is valid: the same answers from either store.
fn bad_ids_methods_names_and_tokens_get_the_same_answers(kind: Kind) {
    let d = Deployment::start(kind, 1);
    let (api, admin) = (&d.api, &d.admin);
    for path in [
        "/api/jobs/abc",
        "/api/jobs/1e3",
        "/api/jobs/9223372036854775808",
        "/api/jobs/abc/image.png",
        "/api/jobs/abc/events",
    ] {
        let (status, body) = api.get(admin, path);
        let v: Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(
            (status, v["error"].as_str()),
            (404, Some("job not found")),
            "{path}"
        );
    }
    let r = client()
        .get(format!("{}/api/me", api.base))
        .header("Authorization", format!("Bearer {admin}"))
        .header("Authorization", "Bearer bad")
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    let (status, _) = api.get(admin, "/api/me");
    assert_eq!(status, 200);
    // A method a route does not take: 405, its methods in Allow, a JSON error.
    let r = client()
        .put(format!("{}/api/jobs", api.base))
        .bearer_auth(admin)
        .send()
        .unwrap();
    assert_eq!(r.status().as_u16(), 405);
    let allow = r.headers()["allow"].to_str().unwrap().to_string();
    assert!(allow.contains("GET") && allow.contains("POST"), "{allow}");
    let v: Value = r.json().unwrap();
    assert!(v["error"].as_str().unwrap().contains("method"), "{v}");
    // What the client sent is quoted back at most a kilobyte of it.
    let name = "x".repeat(1 << 20);
    let (status, v) = api.post_job(
        admin,
        &serde_json::json!({"scene_name": name, "params": {}}),
    );
    assert_eq!(
        (status, v["path"].as_str()),
        (422, Some("scene_name")),
        "{v}"
    );
    assert!(v.to_string().len() < 2048, "{} bytes", v.to_string().len());
}
both!(bad_ids_methods_names_and_tokens_get_the_same_answers);

/// A finished job's image in ranges, as one box's file server gives them, and its length
/// by HEAD: the same answers from either store (the farm streams it out of the store).
fn a_finished_image_is_served_in_ranges(kind: Kind) {
    let d = Deployment::start(kind, 1);
    let (api, admin) = (&d.api, &d.admin);
    let id = api.submit(admin, ppm_params());
    let whole = api.wait_done(admin, id);
    let len = whole.len();
    let url = format!("{}/api/jobs/{id}/image.exr", api.base);
    let ranged = |range: &str| {
        let r = client()
            .get(&url)
            .bearer_auth(admin)
            .header("Range", range)
            .send()
            .unwrap();
        let status = r.status().as_u16();
        let content_range = r
            .headers()
            .get("content-range")
            .map(|v| v.to_str().unwrap().to_string());
        (status, content_range, r.bytes().unwrap().to_vec())
    };
    assert_eq!(
        ranged("bytes=0-10"),
        (206, Some(format!("bytes 0-10/{len}")), whole[..11].to_vec())
    );
    let tail = format!("bytes {}-{}/{len}", len - 5, len - 1);
    assert_eq!(
        ranged("bytes=-5"),
        (206, Some(tail), whole[len - 5..].to_vec())
    );
    for bad in [
        "bytes=5-1".to_string(),
        format!("bytes={len}-"),
        "bytes=abc".into(),
    ] {
        let (status, content_range, _) = ranged(&bad);
        assert_eq!(
            (status, content_range),
            (416, Some(format!("bytes */{len}"))),
            "{bad}"
        );
    }
    let r = client().head(&url).bearer_auth(admin).send().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(r.headers()["accept-ranges"], "bytes");
    assert_eq!(r.headers()["content-length"], len.to_string().as_str());
}
both!(a_finished_image_is_served_in_ranges);
