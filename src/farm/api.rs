//! `photonbox serve --store postgres://...`: the farm's API instance. It keeps nothing but
//! the store's connections: every job, task, result and user is in PostgreSQL, so any
//! number of instances serve the same farm, and an instance killed and restarted loses
//! nothing. Jobs are admitted by the same checks as the one-box server
//! (`server::submit::admit`), split into tasks (`task::split`) and committed with them in
//! one transaction before the 202. The routes are the one-box server's paths and shapes,
//! those of them the farm has so far (see docs/farm.md, "Limits").

use std::sync::Arc;

use axum::extract::{DefaultBodyLimit, Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde_json::{Value, json};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::download::final_image;
use super::preview::{Encoding, Previews};
use super::snapshot::snapshot;
use super::task::split;
use super::workers::WorkerList;
use super::{FarmError, FarmJob, OverLimit, Queue, UserLimits, epoch_seconds};
use crate::server::api::{scene_json, scene_list, visible};
use crate::server::auth::{User, bearer, token_hash};
use crate::server::error::ApiError;
use crate::server::jobs::JobSpec;
use crate::server::needs::Limits;
use crate::server::scenes::SceneCatalog;
use crate::server::store::JobRow;
use crate::server::submit::{Admitted, admit, check_reference, over_storage, queue_full};
use crate::server::views::{AuthErrors, ErrorBody, JobList, JobView, SceneList};
use crate::server::web;

/// One API instance's state.
pub struct FarmApi {
    pub queue: Queue,
    pub catalog: Arc<SceneCatalog>,
    pub limits: Limits,
    pub(crate) bodies: crate::server::body::BodyReader,
    pub previews: Previews,
}

type ApiRef = Arc<FarmApi>;

/// The one-box server's routes that the farm has, with the same paths and shapes (the
/// gallery among them), and the farm's own (`/api/workers`).
pub fn router(api: ApiRef) -> Router {
    let body_limit = api.limits.body_bytes;
    // The one-box server's document, and the farm's own routes in it.
    let (farm_routes, farm_paths) = OpenApiRouter::new()
        .routes(routes!(workers))
        .split_for_parts();
    let mut document = crate::server::api::document(&api.catalog);
    document.merge(farm_paths);
    Router::new()
        .merge(farm_routes)
        .route("/api/jobs", get(list).post(submit))
        .route("/api/jobs/{id}", get(job).delete(delete))
        .route("/api/jobs/{id}/events", get(super::events::job_events))
        .route("/api/jobs/{id}/{file}", get(image))
        .route("/api/scenes", get(scenes))
        .route("/api/scenes/{name}", get(scene))
        .route("/api/me", get(me))
        .route(
            "/api/openapi.json",
            get(move || std::future::ready(Json(document.clone()))),
        )
        .route("/", get(web::index))
        .route("/web/{file}", get(web::web_file))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .fallback(|| async { ApiError::not_found("route") })
        .method_not_allowed_fallback(|| async { ApiError::method_not_allowed() })
        .layer(DefaultBodyLimit::max(body_limit))
        .with_state(api)
}

pub(super) fn store_error(e: FarmError) -> ApiError {
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
pub(super) async fn visible_job(api: &FarmApi, user: &User, id: i64) -> Result<FarmJob, ApiError> {
    match api.queue.job(id).await.map_err(store_error)? {
        Some(j) if visible(user, &j.row) => Ok(j),
        _ => Err(ApiError::not_found("job")),
    }
}

/// A job id from the path: anything else names no job (404, as on one box).
pub(super) fn job_id(raw: &str) -> Result<i64, ApiError> {
    raw.parse().map_err(|_| ApiError::not_found("job"))
}

async fn submit(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Response, ApiError> {
    let user = user(&api, &headers).await?;
    let body = api.bodies.read(user.id, &headers, body).await?;
    let Admitted {
        row,
        spec,
        uploaded,
        work,
        size: admitted_size,
    } = admit(&api.catalog, &api.limits, &user, body).await?;
    if let Some(reference) = spec.reference_job {
        let seen = match api.queue.job(reference).await.map_err(store_error)? {
            Some(j) if visible(&user, &j.row) => Some((j.row.status, j.row.size)),
            _ => None,
        };
        check_reference(reference, seen, admitted_size)?;
    }
    let height = row.size.map_or(0, |(_, h)| h);
    let tasks = split(&spec.render, work, height, row.memory_bytes);
    let limits = UserLimits {
        max_queued: api.limits.max_queued_per_user as i64,
        storage_bytes: api.limits.storage_bytes_per_user,
    };
    let submitted = api
        .queue
        .submit_job(&row, uploaded.as_deref(), &tasks, limits)
        .await
        .map_err(store_error)?;
    let id = match submitted {
        Ok(id) => id,
        Err(OverLimit::Queued) => return Err(queue_full(api.limits.max_queued_per_user)),
        Err(OverLimit::Storage { used }) => {
            let adding = row.scene_bytes + row.result_estimate;
            return Err(over_storage(used, limits.storage_bytes, adding));
        }
    };
    let link = format!("/api/jobs/{id}");
    let body = json!({"id": id, "status": "queued", "links": {"self": link}});
    Ok((StatusCode::ACCEPTED, [(header::LOCATION, link)], Json(body)).into_response())
}

async fn job(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<JobView>, ApiError> {
    let user = user(&api, &headers).await?;
    let job = visible_job(&api, &user, job_id(&id)?).await?;
    Ok(Json(job_view(&job, &user, epoch_seconds())))
}

/// The jobs the user may see, newest first (at most [`LIST_MAX`]).
async fn list(State(api): State<ApiRef>, headers: HeaderMap) -> Result<Json<JobList>, ApiError> {
    let user = user(&api, &headers).await?;
    let rows = api
        .queue
        .visible_jobs(user.id, user.admin, LIST_MAX)
        .await
        .map_err(store_error)?;
    let now = epoch_seconds();
    let jobs = rows.iter().map(|j| job_view(j, &user, now)).collect();
    Ok(Json(JobList { jobs }))
}

/// The most jobs one listing shows.
const LIST_MAX: i64 = 500;

/// A job as `GET /api/jobs/{id}` shows it: the one-box server's view, field for field.
fn job_view(job: &FarmJob, user: &User, now: f64) -> JobView {
    let mine = job.row.user_id == user.id;
    JobView::of(&job.row, &snapshot(job, now), job.owner.clone(), mine)
}

/// Cancel a queued or running job; delete a finished one, with its tasks and images (as
/// the one-box server does).
async fn delete(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let user = user(&api, &headers).await?;
    let row = visible_job(&api, &user, job_id(&id)?).await?.row;
    if !(user.admin || row.user_id == user.id) {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            None,
            "this public job is read-only for you",
        ));
    }
    if row.status.is_final() {
        if api.queue.delete_job(row.id).await.map_err(store_error)? {
            return Ok(StatusCode::NO_CONTENT.into_response());
        }
        return Err(ApiError::not_found("job"));
    }
    api.queue.cancel_job(row.id).await.map_err(store_error)?;
    let row = visible_job(&api, &user, row.id).await?.row;
    Ok(Json(json!({"id": row.id, "status": row.status.as_str()})).into_response())
}

async fn scenes(
    State(api): State<ApiRef>,
    headers: HeaderMap,
) -> Result<Json<SceneList>, ApiError> {
    user(&api, &headers).await?;
    Ok(Json(scene_list(&api.catalog)))
}

async fn scene(
    State(api): State<ApiRef>,
    headers: HeaderMap,
    Path(name): Path<String>,
) -> Result<Json<Value>, ApiError> {
    user(&api, &headers).await?;
    scene_json(&api.catalog, &name)
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
    let row = visible_job(&api, &user, job_id(&id)?).await?.row;
    let exr = encoding == Encoding::Exr;
    if row.status.is_final() {
        if let Some(r) = final_image(&api.queue, row.id, exr, mime, &headers).await? {
            return Ok(r);
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

/// The farm's workers, each with its last heartbeat (admins only).
#[utoipa::path(get, path = "/api/workers", tag = "farm", security(("bearer" = [])),
    responses((status = 200, description = "Every worker of the farm", body = WorkerList),
        (status = 403, description = "Not an admin", body = ErrorBody), AuthErrors))]
async fn workers(
    State(api): State<ApiRef>,
    headers: HeaderMap,
) -> Result<Json<WorkerList>, ApiError> {
    let user = user(&api, &headers).await?;
    if !user.admin {
        return Err(ApiError::new(StatusCode::FORBIDDEN, None, "admins only"));
    }
    let workers = api.queue.workers().await.map_err(store_error)?;
    Ok(Json(WorkerList { workers }))
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
