//! `POST /api/jobs`: a job's admission. The token was checked from the headers before this
//! runs (the `User` extractor); here the body is read within its size and time limits, the
//! request, params and scene are checked, the job's memory, work and storage are checked
//! against the limits, and the job is committed to the store before its 202.

use axum::Json;
use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::AppRef;
use super::api::{blocking, visible};
use super::auth::User;
use super::body::ReadBody;
use super::error::ApiError;
use super::jobs::{JobRequest, JobSpec, from_json};
use super::needs::{JobNeeds, Limits};
use super::scenes::{SceneCatalog, resolve_request};
use super::store::{JobRow, Status, now};
use super::views::{AuthErrors, ErrorBody, SelfLink, Submitted};
use crate::spec::SpecForm;

/// Submit a job: a scene (yours, or a built-in one by name) and its parameters. It is
/// committed to the store before the 202, and queued (round-robin over users).
#[utoipa::path(post, path = "/api/jobs", tag = "jobs", security(("bearer" = [])),
    request_body = JobRequest,
    responses(
        (status = 202, description = "Accepted and queued", body = Submitted),
        (status = 400, description = "Malformed JSON, or not an object", body = ErrorBody),
        (status = 408, description = "The body did not arrive in time", body = ErrorBody),
        (status = 413, description = "The body is over the server's limit", body = ErrorBody),
        (status = 422, description = "A field is invalid or over a limit: `path` names it",
            body = ErrorBody),
        (status = 429, description = "You have the most queued jobs allowed", body = ErrorBody),
        (status = 503, description = "The server is reading as many large bodies as it \
            takes at once: try again", body = ErrorBody,
            headers(("Retry-After" = u32, description = "Seconds to wait before trying again"))),
        AuthErrors,
    ))]
pub async fn submit_job(
    State(app): State<AppRef>,
    user: User,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let limits = &app.config.limits;
    let body = app.bodies.read(user.id, &headers, body).await?;
    let admitted = admit(&app.catalog, limits, &user, body).await?;
    if let Some(reference) = admitted.spec.reference_job {
        let seen = match app.jobs.view(reference) {
            Some((row, _)) if visible(&user, &row) => Some((row.status, row.size)),
            _ => None,
        };
        check_reference(reference, seen, admitted.size)?;
    }
    let Admitted { row, uploaded, .. } = admitted;
    let id = commit(&app, &user, row, uploaded).await?;
    let body = Submitted {
        id,
        status: Status::Queued,
        links: SelfLink {
            self_: format!("/api/jobs/{id}"),
        },
    };
    let location = [(header::LOCATION, body.links.self_.clone())];
    Ok((StatusCode::ACCEPTED, location, Json(body)).into_response())
}

/// A job request that passed its checks, ready to commit.
pub(crate) struct Admitted {
    pub row: JobRow,
    pub spec: JobSpec,
    /// The uploaded scene's text (None: a built-in scene).
    pub uploaded: Option<std::sync::Arc<str>>,
    pub size: (u32, u32),
    /// The engine's estimate of the render's work (`render::Needs::work`).
    pub work: f64,
}

/// Check a job request (`POST /api/jobs`'s body) for `user`: its fields, params and scene,
/// and its needs against `limits`. Every store's front end admits jobs through here.
pub(crate) async fn admit(
    catalog: &std::sync::Arc<SceneCatalog>,
    limits: &Limits,
    user: &User,
    body: ReadBody,
) -> Result<Admitted, ApiError> {
    let ReadBody { value, share } = body;
    let req: JobRequest = from_json(value, "")?;
    let form: SpecForm = from_json(req.params.unwrap_or(json!({})), "params")?;
    let spec = JobSpec::from_form(&form)?;
    // Reading and parsing the scene (and its meshes) is blocking work.
    let (catalog, render, limits2) = (catalog.clone(), spec.render.clone(), limits.clone());
    let (scene_name, scene_value) = (req.scene_name.clone(), req.scene);
    let (scene, needs) = blocking(move || {
        // The body's share of the budget goes back once its scene is parsed, even if the
        // client has gone.
        let _share = share;
        let scene = resolve_request(&catalog, scene_value, scene_name.as_deref())?;
        let needs = JobNeeds::estimate(&scene.desc, &render);
        needs.check(&render, &limits2)?;
        Ok((scene, needs))
    })
    .await?;
    let camera = &scene.desc.camera;
    let size = spec.render.resolution((camera.width, camera.height));
    let uploaded = req.scene_name.is_none().then_some(scene.text.clone());
    let row = JobRow {
        id: 0,
        user_id: user.id,
        public: req.public,
        status: Status::Queued,
        scene_name: scene.name.clone(),
        scene_bytes: uploaded.as_ref().map_or(0, |t| t.len() as u64),
        result_bytes: needs.render.result_bytes,
        result_estimate: needs.render.result_bytes,
        memory_bytes: needs.render.memory_bytes,
        params_json: serde_json::to_string(&spec.to_form())
            .map_err(|e| ApiError::internal(e.to_string()))?,
        size: Some(size),
        created: now(),
        started: None,
        finished: None,
        error: None,
        stats_json: None,
    };
    Ok(Admitted {
        row,
        spec,
        uploaded,
        size,
        work: needs.render.work,
    })
}

/// Check the user's queue and storage and commit the job, durable before it is
/// acknowledged; then publish it and queue it. From the checks to the job table, one
/// submission at a time (see `App::submit`).
async fn commit(
    app: &AppRef,
    user: &User,
    mut row: JobRow,
    uploaded: Option<std::sync::Arc<str>>,
) -> Result<i64, ApiError> {
    let limits = &app.config.limits;
    let _submitting = app.submit.lock().await;
    if app.jobs.queued_of(user.id) >= limits.max_queued_per_user {
        return Err(queue_full(limits.max_queued_per_user));
    }
    check_storage(app, user, row.scene_bytes + row.result_estimate)?;
    let (app2, row2) = (app.clone(), row.clone());
    row.id = blocking(move || Ok(app2.store.insert_job(&row2, uploaded.as_deref())?)).await?;
    let (id, memory) = (row.id, row.memory_bytes);
    app.jobs.insert(row);
    app.scheduler.enqueue(id, user.id, memory);
    Ok(id)
}

/// A user's storage quota: their uploaded scenes and result files, with what this job adds
/// (`adding`: its scene and an estimate of its images), must fit.
fn check_storage(app: &AppRef, user: &User, adding: u64) -> Result<(), ApiError> {
    let quota = app.config.limits.storage_bytes_per_user;
    let used = app.jobs.storage_of(user.id);
    if used + adding > quota {
        return Err(over_storage(used, quota, adding));
    }
    Ok(())
}

/// The answer to a user whose queued jobs are at the limit (the farm's too).
pub(crate) fn queue_full(limit: usize) -> ApiError {
    ApiError::new(
        StatusCode::TOO_MANY_REQUESTS,
        Some("limits.max_queued_per_user"),
        format!("you already have {limit} queued jobs, the limit: wait for some to finish"),
    )
}

/// The answer to a user whose jobs take `used` bytes of `quota`, when one `adding` more
/// would not fit (the farm's too).
pub(crate) fn over_storage(used: u64, quota: u64, adding: u64) -> ApiError {
    ApiError::invalid(
        "limits.storage_per_user",
        format!(
            "your jobs take {} MiB of your {} MiB storage and this one needs about {} MiB more: \
             delete some finished jobs",
            used.div_ceil(1 << 20),
            quota >> 20,
            adding.div_ceil(1 << 20)
        ),
    )
}

/// A reference job must be one the user may see (`seen`: its status and size, None if the
/// user may not see it), be done, and have this job's `size` (the farm's check too).
pub(crate) fn check_reference(
    reference: i64,
    seen: Option<(Status, Option<(u32, u32)>)>,
    size: (u32, u32),
) -> Result<(), ApiError> {
    let invalid = |msg: String| ApiError::invalid("params.reference_job", msg);
    let Some((status, ref_size)) = seen else {
        return Err(invalid(format!("no job {reference} that you may see")));
    };
    if status != Status::Done {
        return Err(invalid(format!(
            "job {reference} is {}: a reference must be done",
            status.as_str()
        )));
    }
    if ref_size != Some(size) {
        let shown = ref_size.map_or("?x?".to_string(), |(w, h)| format!("{w}x{h}"));
        return Err(invalid(format!(
            "job {reference} is {shown}, this job {}x{}: a reference must have the same width and height",
            size.0, size.1
        )));
    }
    Ok(())
}
