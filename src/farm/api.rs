//! `photonbox serve --store postgres://...`: the farm's API instance. It keeps nothing but
//! the store's connections: every job, task, result and user is in PostgreSQL, so any
//! number of instances serve the same farm, and an instance killed and restarted loses
//! nothing. Jobs are admitted by the same checks as the one-box server
//! (`server::submit::admit`), split into tasks (`task::split`) and committed with them in
//! one transaction before the 202. The routes are the one-box server's paths and shapes,
//! those of them the farm has so far (see docs/farm.md, "Limits").

use std::sync::Arc;
use std::time::Duration;

use axum::extract::{DefaultBodyLimit, Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde_json::{Value, json};

use super::preview::{Encoding, Previews};
use super::task::split;
use super::{FarmError, Queue, TaskCount};
use crate::server::auth::{User, bearer, token_hash};
use crate::server::error::ApiError;
use crate::server::jobs::JobSpec;
use crate::server::needs::Limits;
use crate::server::scenes::SceneCatalog;
use crate::server::store::{JobRow, Status};
use crate::server::submit::{Admitted, admit, read_body};

/// One API instance's state.
pub struct FarmApi {
    pub queue: Queue,
    pub catalog: Arc<SceneCatalog>,
    pub limits: Limits,
    pub body_timeout: Duration,
    pub previews: Previews,
}

type ApiRef = Arc<FarmApi>;

pub fn router(api: ApiRef) -> Router {
    let body_limit = api.limits.body_bytes;
    Router::new()
        .route("/api/jobs", get(list).post(submit))
        .route("/api/jobs/{id}", get(job).delete(cancel))
        .route("/api/jobs/{id}/events", get(super::events::job_events))
        .route("/api/jobs/{id}/{file}", get(image))
        .route("/api/workers", get(workers))
        .route("/api/me", get(me))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .fallback(|| async { ApiError::not_found("route") })
        .layer(DefaultBodyLimit::max(body_limit))
        .with_state(api)
}

fn store_error(e: FarmError) -> ApiError {
    ApiError::new(
        StatusCode::SERVICE_UNAVAILABLE,
        None,
        format!("the store: {e}"),
    )
}

/// The user of the request's bearer token.
pub(super) async fn user(api: &FarmApi, headers: &HeaderMap) -> Result<User, ApiError> {
    let token = bearer(headers)?;
    api.queue
        .user_by_token_hash(&token_hash(token))
        .await
        .map_err(store_error)?
        .ok_or_else(ApiError::unauthorized)
}

/// A job the user may see (others' private jobs do not exist for them: 404).
pub(super) async fn visible_job(
    api: &FarmApi,
    user: &User,
    id: i64,
) -> Result<(JobRow, TaskCount), ApiError> {
    match api.queue.job(id).await.map_err(store_error)? {
        Some((row, p)) if user.admin || row.user_id == user.id || row.public => Ok((row, p)),
        _ => Err(ApiError::not_found("job")),
    }
}

pub(super) fn job_id(raw: &str) -> Result<i64, ApiError> {
    raw.parse()
        .map_err(|_| ApiError::invalid("id", format!("{raw:?} is not a job id")))
}

async fn submit(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Response, ApiError> {
    let user = user(&api, &headers).await?;
    let value = read_body(api.limits.body_bytes, api.body_timeout, &headers, body).await?;
    let Admitted {
        row,
        spec,
        uploaded,
        work,
        ..
    } = admit(&api.catalog, &api.limits, &user, value).await?;
    if spec.reference_job.is_some() {
        return Err(ApiError::invalid(
            "params.reference_job",
            "a reference job is not supported on the farm yet",
        ));
    }
    let queued = api
        .queue
        .queued_jobs_of(user.id)
        .await
        .map_err(store_error)?;
    if queued >= api.limits.max_queued_per_user as i64 {
        return Err(ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            Some("limits.max_queued_per_user"),
            format!("you already have {queued} queued jobs, the limit: wait for some to finish"),
        ));
    }
    let height = row.size.map_or(0, |(_, h)| h);
    let tasks = split(&spec.render, work, height, row.memory_bytes);
    let id = api
        .queue
        .submit_job(&row, uploaded.as_deref(), &tasks)
        .await
        .map_err(store_error)?;
    let link = format!("/api/jobs/{id}");
    let body = json!({"id": id, "status": "queued", "links": {"self": link}});
    Ok((StatusCode::ACCEPTED, [(header::LOCATION, link)], Json(body)).into_response())
}

async fn job(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let user = user(&api, &headers).await?;
    let (row, tasks) = visible_job(&api, &user, job_id(&id)?).await?;
    Ok(Json(job_json(&row, tasks, &user)))
}

/// The jobs the user may see, newest first (at most [`LIST_MAX`]).
async fn list(State(api): State<ApiRef>, headers: HeaderMap) -> Result<Json<Value>, ApiError> {
    let user = user(&api, &headers).await?;
    let rows = api
        .queue
        .visible_jobs(user.id, user.admin, LIST_MAX)
        .await
        .map_err(store_error)?;
    let jobs: Vec<Value> = rows.iter().map(|(r, p)| job_json(r, *p, &user)).collect();
    Ok(Json(json!({ "jobs": jobs })))
}

/// The most jobs one listing shows.
const LIST_MAX: i64 = 500;

/// A job as `GET /api/jobs/{id}` shows it (the one-box server's fields that the farm has).
fn job_json(row: &JobRow, tasks: TaskCount, user: &User) -> Value {
    let raw = |t: &Option<String>| {
        t.as_deref()
            .and_then(|t| serde_json::from_str::<Value>(t).ok())
    };
    json!({
        "id": row.id,
        "mine": row.user_id == user.id,
        "public": row.public,
        "scene": row.scene_name,
        "params": serde_json::from_str::<Value>(&row.params_json).unwrap_or(Value::Null),
        "status": row.status.as_str(),
        "progress": if row.status == Status::Done { 1.0 } else { tasks.progress() },
        "created": row.created,
        "started": row.started,
        "finished": row.finished,
        "error": row.error,
        "stats": raw(&row.stats_json),
    })
}

async fn cancel(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let user = user(&api, &headers).await?;
    let (row, _) = visible_job(&api, &user, job_id(&id)?).await?;
    if !(user.admin || row.user_id == user.id) {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            None,
            "only its owner or an admin may cancel a job",
        ));
    }
    api.queue.cancel_job(row.id).await.map_err(store_error)?;
    let (row, _) = visible_job(&api, &user, row.id).await?;
    Ok(Json(json!({"id": row.id, "status": row.status.as_str()})))
}

/// The job's image: the final one, or while it runs a preview of its tasks done so far
/// (`preview.rs`).
async fn image(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path((id, file)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let user = user(&api, &headers).await?;
    let (encoding, mime) = match file.as_str() {
        "image.exr" => (Encoding::Exr, "image/x-exr"),
        "image.png" => (Encoding::Png, "image/png"),
        _ => return Err(ApiError::not_found("file")),
    };
    let (row, _) = visible_job(&api, &user, job_id(&id)?).await?;
    let exr = encoding == Encoding::Exr;
    if row.status.is_final() {
        let bytes = api
            .queue
            .job_image(row.id, exr)
            .await
            .map_err(store_error)?;
        if let Some(b) = bytes {
            return Ok(([(header::CONTENT_TYPE, mime)], b).into_response());
        }
    } else if let Some(preview) = preview(&api, &row, encoding).await? {
        let headers = [
            (header::CONTENT_TYPE, mime),
            // The next task's result replaces it.
            (header::CACHE_CONTROL, "no-store"),
        ];
        return Ok((headers, preview).into_response());
    }
    Err(ApiError::new(
        StatusCode::NOT_FOUND,
        Some("file"),
        format!(
            "job {} is {}: it has no image yet",
            row.id,
            row.status.as_str()
        ),
    ))
}

/// The preview of running job `row`, if a task of it is done.
async fn preview(
    api: &FarmApi,
    row: &JobRow,
    encoding: Encoding,
) -> Result<Option<Vec<u8>>, ApiError> {
    let Some(size) = row.size else {
        return Ok(None);
    };
    let spec = JobSpec::from_stored(&row.params_json).map_err(ApiError::internal)?;
    api.previews
        .get(&api.queue, row.id, size, spec.exposure, encoding)
        .await
        .map_err(|e| ApiError::internal(format!("the preview: {e}")))
}

async fn workers(State(api): State<ApiRef>, headers: HeaderMap) -> Result<Json<Value>, ApiError> {
    let user = user(&api, &headers).await?;
    if !user.admin {
        return Err(ApiError::new(StatusCode::FORBIDDEN, None, "admins only"));
    }
    let rows = api.queue.workers().await.map_err(store_error)?;
    Ok(Json(json!({ "workers": rows })))
}

async fn me(State(api): State<ApiRef>, headers: HeaderMap) -> Result<Json<Value>, ApiError> {
    let user = user(&api, &headers).await?;
    Ok(Json(
        json!({"id": user.id, "name": user.name, "admin": user.admin}),
    ))
}

async fn healthz(State(api): State<ApiRef>) -> Response {
    super::probe::health(&api.queue).await
}

async fn metrics(State(api): State<ApiRef>) -> Response {
    super::probe::metrics(&api.queue).await
}
