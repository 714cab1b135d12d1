//! Handler tests without a socket: `server::app(state)` called with tower's `oneshot`, as
//! axum's examples test their routers. Black-box process tests (tests/server/) stay for what
//! needs a process: signals, restarts, connections.

use std::time::Duration;

use axum::body::Body;
use axum::http::{Request, StatusCode, header};
use photonbox::server::{self, App, AppRef, Config, ConnLimits, Limits};
use serde_json::{Value, json};
use tower::ServiceExt;

fn open(data: &std::path::Path) -> (AppRef, String) {
    let config = Config {
        addr: "127.0.0.1:0".into(),
        data: data.to_path_buf(),
        scenes: concat!(env!("CARGO_MANIFEST_DIR"), "/scenes").into(),
        threads: 1,
        max_running: 1,
        cache_bytes: 0,
        limits: Limits::default(),
        conn: ConnLimits {
            max_connections: 16,
            header_timeout: Duration::from_secs(10),
            write_timeout: Duration::from_secs(10),
            drain: Duration::from_secs(1),
        },
        body_timeout: Duration::from_secs(10),
    };
    let (app, token) = App::open(config).unwrap();
    (app, token.expect("a new data folder gets an admin token"))
}

/// One request through the router: status and JSON body.
async fn call(app: &AppRef, req: Request<Body>) -> (StatusCode, Value) {
    let resp = server::app(app.clone()).oneshot(req).await.unwrap();
    let status = resp.status();
    let bytes = axum::body::to_bytes(resp.into_body(), 1 << 20)
        .await
        .unwrap();
    (
        status,
        serde_json::from_slice(&bytes).unwrap_or(Value::Null),
    )
}

fn get(path: &str, token: Option<&str>) -> Request<Body> {
    let mut r = Request::get(path);
    if let Some(t) = token {
        r = r.header(header::AUTHORIZATION, format!("Bearer {t}"));
    }
    r.body(Body::empty()).unwrap()
}

#[tokio::test]
async fn tokens_are_required_and_identify_the_user() {
    let dir = tempfile::tempdir().unwrap();
    let (app, admin) = open(dir.path());
    let (status, v) = call(&app, get("/api/me", None)).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    assert_eq!(v["path"], "header.Authorization");
    let (status, v) = call(&app, get("/api/me", Some(&"0".repeat(64)))).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED, "{v}");
    let (status, v) = call(&app, get("/api/me", Some(&admin))).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(v, json!({"id": v["id"], "name": "admin", "admin": true}));
}

#[tokio::test]
async fn the_built_in_scenes_are_listed_from_the_catalogue() {
    let dir = tempfile::tempdir().unwrap();
    let (app, admin) = open(dir.path());
    let (status, v) = call(&app, get("/api/scenes", Some(&admin))).await;
    assert_eq!(status, StatusCode::OK);
    let names: Vec<&str> = v["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"cornell") && names.contains(&"knot"),
        "{names:?}"
    );
    let (status, v) = call(&app, get("/api/scenes/cornell", Some(&admin))).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(v["name"], "cornell");
    let (status, _) = call(&app, get("/api/scenes/..%2Fcornell", Some(&admin))).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn a_bad_parameter_is_named_and_a_good_job_is_queued() {
    let dir = tempfile::tempdir().unwrap();
    let (app, admin) = open(dir.path());
    let post = |body: Value| {
        Request::post("/api/jobs")
            .header(header::AUTHORIZATION, format!("Bearer {admin}"))
            .header(header::CONTENT_TYPE, "application/json")
            .body(Body::from(body.to_string()))
            .unwrap()
    };
    let (status, v) = call(
        &app,
        post(json!({"scene_name": "cornell", "params": {"integrator": "photon", "k": 0}})),
    )
    .await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(v["path"], "params.k");
    let (status, v) = call(&app, post(json!({"scene_name": "cornell"}))).await;
    assert_eq!(status, StatusCode::ACCEPTED, "{v}");
    // No dispatcher runs here: the job waits in the queue, listed as such.
    let id = v["id"].as_i64().unwrap();
    let (status, v) = call(&app, get(&format!("/api/jobs/{id}"), Some(&admin))).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(v["status"], "queued");
    assert_eq!(v["queue_position"], 0);
}
