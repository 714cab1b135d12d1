//! The HTTP API (JSON under /api, bearer tokens), SSE job events, health and metrics.

use std::convert::Infallible;
use std::time::Duration;

use axum::Json;
use axum::Router;
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, FromRequestParts, Path, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use futures_util::stream::{self, Stream, StreamExt};
use serde_json::{Value, json};
use tower::ServiceExt;
use tower_http::services::ServeFile;

use super::auth::{self, User};
use super::error::ApiError;
use super::results::{remove_results, result_path};
use super::state::Snapshot;
use super::store::{JobRow, Status, now};
use super::{AppRef, metrics, submit};

pub fn router(app: AppRef) -> Router {
    let body_limit = app.config.limits.body_bytes;
    Router::new()
        .route("/api/jobs", get(list_jobs).post(submit::submit_job))
        .route("/api/jobs/{id}", get(get_job).delete(delete_job))
        .route(
            "/api/jobs/{id}/image.png",
            get(|s: State<AppRef>, u: User, id: Path<String>, r: Request| {
                image(s, u, id, "png", r)
            }),
        )
        .route(
            "/api/jobs/{id}/image.exr",
            get(|s: State<AppRef>, u: User, id: Path<String>, r: Request| {
                image(s, u, id, "exr", r)
            }),
        )
        .route("/api/jobs/{id}/events", get(job_events))
        .route("/api/scenes", get(list_scenes))
        .route("/api/scenes/{name}", get(get_scene))
        .route("/api/me", get(me))
        .route("/healthz", get(|| async { "ok\n" }))
        .route("/metrics", get(metrics_text))
        .route("/", get(index))
        .route("/web/{file}", get(web_file))
        .fallback(|| async { ApiError::not_found("route") })
        .layer(DefaultBodyLimit::max(body_limit))
        .layer(middleware::from_fn_with_state(app.clone(), metrics::track))
        .with_state(app)
}

/// The gallery (web/): static files embedded in the binary, so a newcomer needs no build
/// step and the server nothing beside itself. The scripts are native ES modules: app.js
/// imports the others by relative URL, so each needs its entry here. (file name, content
/// type, content)
const WEB_FILES: &[(&str, &str, &str)] = &[
    ("app.js", JS, include_str!("../../web/app.js")),
    ("api.js", JS, include_str!("../../web/api.js")),
    ("state.js", JS, include_str!("../../web/state.js")),
    ("format.js", JS, include_str!("../../web/format.js")),
    ("gallery.js", JS, include_str!("../../web/gallery.js")),
    ("submit.js", JS, include_str!("../../web/submit.js")),
    ("job.js", JS, include_str!("../../web/job.js")),
    ("charts.js", JS, include_str!("../../web/charts.js")),
    ("compare.js", JS, include_str!("../../web/compare.js")),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("../../web/style.css"),
    ),
];

/// Module scripts must be served with a JavaScript type or the browser refuses them.
const JS: &str = "text/javascript; charset=utf-8";

/// The page may load only its own files and talk only to this server: an injected script
/// could read the token from localStorage.
const CSP: &str = "default-src 'self'; img-src 'self' blob:; object-src 'none'; base-uri 'none'; \
                   frame-ancestors 'none'";

async fn index() -> Response {
    (
        [(header::CONTENT_SECURITY_POLICY, CSP)],
        Html(include_str!("../../web/index.html")),
    )
        .into_response()
}

async fn web_file(Path(file): Path<String>) -> Result<Response, ApiError> {
    let (_, mime, text) = WEB_FILES
        .iter()
        .find(|(name, _, _)| *name == file)
        .ok_or_else(|| ApiError::not_found("file"))?;
    Ok((
        [
            (header::CONTENT_TYPE, *mime),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        *text,
    )
        .into_response())
}

/// The user a request's bearer token belongs to (SHA-256 looked up in memory, else in the
/// store on a blocking thread).
async fn authenticate(app: &AppRef, headers: &HeaderMap) -> Result<User, ApiError> {
    let hash = auth::token_hash(auth::bearer(headers)?);
    if let Some(u) = app.users.lock().unwrap().get(&hash) {
        return Ok(u.clone());
    }
    let (app2, hash2) = (app.clone(), hash.clone());
    let user = blocking(move || Ok(app2.store.user_by_token_hash(&hash2)?))
        .await?
        .ok_or_else(ApiError::unauthorized)?;
    app.users.lock().unwrap().insert(hash, user.clone());
    app.user_names
        .lock()
        .unwrap()
        .insert(user.id, user.name.clone());
    Ok(user)
}

/// The authenticated user, taken from the headers alone: as an extractor it runs before any
/// body is read, so a request without a valid token is answered 401 without its body being
/// read (or, with `Expect: 100-continue`, without a `100 Continue`).
impl FromRequestParts<AppRef> for User {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, app: &AppRef) -> Result<User, ApiError> {
        authenticate(app, &parts.headers).await
    }
}

pub(super) fn visible(user: &User, row: &JobRow) -> bool {
    user.admin || row.user_id == user.id || row.public
}

fn parse_id(id: &str) -> Result<i64, ApiError> {
    id.parse().map_err(|_| ApiError::not_found("job"))
}

/// A job the user may see (others' private jobs do not exist for them: 404).
fn visible_job(app: &AppRef, user: &User, id: &str) -> Result<(JobRow, Snapshot), ApiError> {
    let id = parse_id(id)?;
    match app.jobs.view(id) {
        Some((row, snap)) if visible(user, &row) => Ok((row, snap)),
        _ => Err(ApiError::not_found("job")),
    }
}

/// A job as the API shows it; `queue_position` as the scheduler reports it (for a queued job).
fn job_json(
    app: &AppRef,
    user: &User,
    row: &JobRow,
    snap: &Snapshot,
    queue_position: Option<usize>,
) -> Value {
    let params: Value = serde_json::from_str(&row.params_json).unwrap_or(Value::Null);
    let stats: Value = row
        .stats_json
        .as_deref()
        .and_then(|s| serde_json::from_str(s).ok())
        .unwrap_or(Value::Null);
    let base = format!("/api/jobs/{}", row.id);
    json!({
        "id": row.id,
        "owner": app.user_name(row.user_id),
        "mine": row.user_id == user.id,
        "public": row.public,
        "scene": row.scene_name,
        "params": params,
        "status": row.status.as_str(),
        "queue_position": queue_position,
        "progress": snap.progress,
        "phase": snap.phase,
        "eta_seconds": snap.eta_seconds,
        "created": row.created,
        "started": row.started,
        "finished": row.finished,
        "error": row.error,
        "stats": stats,
        // What the server planned for (the memory budget admits by it).
        "memory_estimate_bytes": row.memory_bytes,
        "links": {
            "self": base,
            "png": format!("{base}/image.png"),
            "exr": format!("{base}/image.exr"),
            "events": format!("{base}/events"),
        },
    })
}

async fn me(user: User) -> Json<Value> {
    Json(json!({ "id": user.id, "name": user.name, "admin": user.admin }))
}

async fn list_jobs(State(app): State<AppRef>, user: User) -> Result<Json<Value>, ApiError> {
    let positions = app.scheduler.queue_positions();
    let jobs: Vec<Value> = app
        .jobs
        .list(|r| visible(&user, r))
        .iter()
        .map(|(row, snap)| job_json(&app, &user, row, snap, positions.get(&row.id).copied()))
        .collect();
    Ok(Json(json!({ "jobs": jobs })))
}

async fn get_job(
    State(app): State<AppRef>,
    user: User,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let (row, snap) = visible_job(&app, &user, &id)?;
    let position = app.scheduler.queue_position(row.id);
    Ok(Json(job_json(&app, &user, &row, &snap, position)))
}

async fn delete_job(
    State(app): State<AppRef>,
    user: User,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let (row, _) = visible_job(&app, &user, &id)?;
    if !(user.admin || row.user_id == user.id) {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            None,
            "this public job is read-only for you",
        ));
    }
    let id = row.id;
    if row.status.is_final() {
        let app2 = app.clone();
        blocking(move || {
            app2.store.delete_job(id)?;
            remove_results(&app2.config.data, id, &["png", "exr", "ppmstate"]);
            Ok(())
        })
        .await?;
        app.jobs.remove(id);
        return Ok(StatusCode::NO_CONTENT.into_response());
    }
    if app.scheduler.dequeue(id) {
        let app2 = app.clone();
        blocking(move || {
            app2.commit_job(id, |r| {
                r.status = Status::Cancelled;
                r.finished = Some(now());
            });
            Ok(())
        })
        .await?;
        return Ok(Json(json!({ "id": id, "status": "cancelled" })).into_response());
    }
    if app.scheduler.cancel_running(id) {
        // Wait (briefly) until the render has stopped and released its memory.
        if let Some(live) = app.jobs.live(id) {
            let mut rx = live.subscribe();
            let stopped = rx.wait_for(|s| s.status.is_final() || s.status == Status::Queued);
            let _ = tokio::time::timeout(Duration::from_secs(5), stopped).await;
        }
        let status = app.jobs.row(id).map_or(Status::Cancelled, |r| r.status);
        return Ok(Json(json!({ "id": id, "status": status.as_str() })).into_response());
    }
    // Between queue and pool (a race with the dispatcher): the client may retry.
    Err(ApiError::new(
        StatusCode::CONFLICT,
        None,
        "the job is starting; try again",
    ))
}

/// A job's final image (`ext`: png or exr), or its latest preview. Streamed from the file
/// (tower-http's `ServeFile`: chunks, not the whole file in memory), with `Range`,
/// conditional requests and a cheap `HEAD` (axum answers it from the same handler without a
/// body). A preview replaced meanwhile (by a rename) does not disturb a download in flight: it
/// reads the file it opened.
async fn image(
    State(app): State<AppRef>,
    user: User,
    Path(id): Path<String>,
    ext: &'static str,
    req: Request,
) -> Result<Response, ApiError> {
    let mime = if ext == "png" {
        "image/png"
    } else {
        "image/x-exr"
    };
    let (row, _) = visible_job(&app, &user, &id)?;
    let path = result_path(&app.config.data, row.id, ext);
    let mut req = req;
    if !row.status.is_final() {
        // A preview is replaced by the next pass: a range of it could join two files.
        req.headers_mut().remove(header::RANGE);
        req.headers_mut().remove(header::IF_RANGE);
    }
    let mut served = ServeFile::new(path)
        .oneshot(req)
        .await
        .map_err(|e| ApiError::internal(format!("serving the image: {e}")))?;
    if served.status() == StatusCode::NOT_FOUND {
        // The file server's 404 (no file yet) in the API's words.
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            None,
            format!("no image yet: the job is {}", row.status.as_str()),
        ));
    }
    if served.status().is_success() {
        let h = served.headers_mut();
        h.insert(header::CONTENT_TYPE, header::HeaderValue::from_static(mime));
        if !row.status.is_final() {
            h.insert(
                header::ACCEPT_RANGES,
                header::HeaderValue::from_static("none"),
            );
            h.insert(
                header::CACHE_CONTROL,
                header::HeaderValue::from_static("no-store"),
            );
        }
    }
    Ok(served.map(Body::new))
}

/// SSE: `status`, `progress`, `preview`, then one final `done|failed|cancelled`. A client
/// that connects late first gets the current status and progress.
async fn job_events(
    State(app): State<AppRef>,
    user: User,
    Path(id): Path<String>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let (row, _) = visible_job(&app, &user, &id)?;
    let live = app
        .jobs
        .live(row.id)
        .ok_or_else(|| ApiError::not_found("job"))?;
    let rx = live.subscribe();
    drop(live);
    let shutdown = app.shutdown.subscribe();
    struct St {
        rx: tokio::sync::watch::Receiver<Snapshot>,
        shutdown: tokio::sync::watch::Receiver<bool>,
        last: Option<Snapshot>,
        ended: bool,
    }
    let st = St {
        rx,
        shutdown,
        last: None,
        ended: false,
    };
    let events = stream::unfold(st, |mut st| async move {
        if st.ended {
            return None;
        }
        loop {
            if *st.shutdown.borrow() {
                return None;
            }
            let snap = st.rx.borrow_and_update().clone();
            let evs = diff_events(st.last.as_ref(), &snap);
            if !evs.is_empty() {
                st.ended = snap.status.is_final();
                st.last = Some(snap);
                return Some((evs, st));
            }
            tokio::select! {
                r = st.rx.changed() => if r.is_err() { return None; },
                _ = st.shutdown.changed() => return None,
            }
        }
    })
    .flat_map(|evs| stream::iter(evs.into_iter().map(Ok)));
    Ok(Sse::new(events).keep_alive(KeepAlive::default()))
}

fn event(name: &str, snap: &Snapshot) -> Event {
    Event::default()
        .event(name)
        .data(serde_json::to_string(snap).unwrap_or_default())
}

/// The events that take a client from `last` to `now`.
fn diff_events(last: Option<&Snapshot>, now: &Snapshot) -> Vec<Event> {
    let mut out = Vec::new();
    if last.is_none_or(|l| l.status != now.status) {
        out.push(event("status", now));
    }
    if last.is_none_or(|l| l.progress != now.progress || l.phase != now.phase) {
        out.push(event("progress", now));
    }
    if last.map_or(now.previews > 0, |l| now.previews > l.previews) {
        out.push(event("preview", now));
    }
    if now.status.is_final() {
        out.push(event(now.status.as_str(), now));
    }
    out
}

async fn list_scenes(State(app): State<AppRef>, _user: User) -> Result<Json<Value>, ApiError> {
    let scenes: Vec<Value> = app
        .catalog
        .list()
        .into_iter()
        .map(|(name, description)| json!({ "name": name, "description": description }))
        .collect();
    Ok(Json(json!({ "scenes": scenes })))
}

async fn get_scene(
    State(app): State<AppRef>,
    _user: User,
    Path(name): Path<String>,
) -> Result<Json<Value>, ApiError> {
    app.catalog
        .json(&name)
        .map(Json)
        .ok_or_else(|| ApiError::not_found("scene"))
}

async fn metrics_text(State(app): State<AppRef>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        metrics::render(&app),
    )
        .into_response()
}

/// Run blocking work (SQLite, file reads, scene parsing) off the async worker threads.
pub(super) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
}
