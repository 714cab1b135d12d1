//! `POST /api/jobs`: a job's admission. The token was checked from the headers before this
//! runs (the `User` extractor); here the body is read within its size and time limits, the
//! request, params and scene are checked, the job's memory, work and storage are checked
//! against the limits, and the job is committed to the store before its 202.

use axum::Json;
use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

use super::AppRef;
use super::api::{blocking, visible};
use super::auth::User;
use super::error::ApiError;
use super::jobs::{JobRequest, ParamsJson, from_json, resolve_scene};
use super::needs::JobNeeds;
use super::store::{JobRow, Status, now};

pub async fn submit_job(
    State(app): State<AppRef>,
    user: User,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    // The token was checked (the `User` extractor) before any of the body is read; a body
    // declared too large is refused before it is read too.
    let limit = app.config.limits.body_bytes;
    let too_large = || {
        ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            Some("body"),
            format!("request body larger than the limit of {limit} bytes"),
        )
    };
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    let read = tokio::time::timeout(app.config.body_timeout, axum::body::to_bytes(body, limit));
    let body = read.await.map_err(|_| {
        ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            Some("body"),
            format!(
                "the request body did not arrive within {} s",
                app.config.body_timeout.as_secs_f64()
            ),
        )
    })?;
    let body = body.map_err(|e| {
        if over_limit(&e) {
            too_large()
        } else {
            ApiError::new(
                StatusCode::BAD_REQUEST,
                Some("body"),
                format!("reading the body: {e}"),
            )
        }
    })?;
    let value: Value = serde_json::from_slice(&body).map_err(|e| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            Some("body"),
            format!("malformed JSON: {e}"),
        )
    })?;
    if !value.is_object() {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            Some("body"),
            "expected a JSON object",
        ));
    }
    let req: JobRequest = from_json(value, "")?;
    let params_json: ParamsJson = from_json(req.params.unwrap_or(json!({})), "params")?;
    let params = params_json.to_params()?;
    let limits = &app.config.limits;
    // Reading and parsing the scene (and its meshes) is blocking work.
    let (app2, render) = (app.clone(), params.render.clone());
    let (scene_name, scene_value) = (req.scene_name.clone(), req.scene);
    let (mut scene, needs) = blocking(move || {
        let scene = resolve_scene(&app2.catalog, scene_value, scene_name.as_deref())?;
        let needs = JobNeeds::estimate(&scene.desc, &render);
        needs.check(&render, &app2.config.limits)?;
        Ok((scene, needs))
    })
    .await?;
    if let Some(reference) = params.reference_job {
        let p = &params.render;
        let size = (
            p.width.unwrap_or(scene.desc.camera.width),
            p.height.unwrap_or(scene.desc.camera.height),
        );
        check_reference(&app, &user, reference, size)?;
    }
    // From the checks to the job table, one submission at a time (see `App::submit`).
    let _submitting = app.submit.lock().await;
    if app.jobs.queued_of(user.id) >= limits.max_queued_per_user {
        return Err(ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            Some("limits.max_queued_per_user"),
            format!(
                "you already have {} queued jobs, the limit: wait for some to finish",
                limits.max_queued_per_user
            ),
        ));
    }
    let scene_text = req
        .scene_name
        .is_none()
        .then(|| std::mem::take(&mut scene.text));
    let scene_bytes = scene_text.as_ref().map_or(0, |t| t.len() as u64);
    check_storage(&app, &user, scene_bytes + needs.result_bytes)?;
    let mut row = JobRow {
        id: 0,
        user_id: user.id,
        public: req.public,
        status: Status::Queued,
        scene_name: scene.name.clone(),
        scene_bytes,
        result_bytes: needs.result_bytes,
        result_estimate: needs.result_bytes,
        memory_bytes: needs.memory_bytes,
        params_json: serde_json::to_string(&params_json)
            .map_err(|e| ApiError::internal(e.to_string()))?,
        created: now(),
        started: None,
        finished: None,
        error: None,
        stats_json: None,
    };
    // Durable before it is acknowledged.
    let (app2, row2) = (app.clone(), row.clone());
    row.id = blocking(move || Ok(app2.store.insert_job(&row2, scene_text.as_deref())?)).await?;
    let id = row.id;
    app.jobs.insert(row);
    app.scheduler.enqueue(id, user.id, needs.memory_bytes);
    let body =
        json!({ "id": id, "status": "queued", "links": { "self": format!("/api/jobs/{id}") } });
    Ok((StatusCode::ACCEPTED, Json(body)).into_response())
}

/// A user's storage quota: their uploaded scenes and result files, with what this job adds
/// (`adding`: its scene and an estimate of its images), must fit.
fn check_storage(app: &AppRef, user: &User, adding: u64) -> Result<(), ApiError> {
    let quota = app.config.limits.storage_bytes_per_user;
    let used = app.jobs.storage_of(user.id);
    if used + adding > quota {
        return Err(ApiError::invalid(
            "limits.storage_per_user",
            format!(
                "your jobs take {} MiB of your {} MiB storage and this one needs about {} MiB more: \
                 delete some finished jobs",
                used.div_ceil(1 << 20),
                quota >> 20,
                adding.div_ceil(1 << 20)
            ),
        ));
    }
    Ok(())
}

/// Whether reading a body failed because it passed the limit.
fn over_limit(e: &axum::Error) -> bool {
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = source {
        if err.is::<http_body_util::LengthLimitError>() {
            return true;
        }
        source = err.source();
    }
    false
}

/// A reference job must be one the user may see, be done, and have this job's `size`.
fn check_reference(
    app: &AppRef,
    user: &User,
    reference: i64,
    size: (u32, u32),
) -> Result<(), ApiError> {
    let invalid = |msg: String| ApiError::invalid("params.reference_job", msg);
    let row = match app.jobs.view(reference) {
        Some((row, _)) if visible(user, &row) => row,
        _ => return Err(invalid(format!("no job {reference} that you may see"))),
    };
    if row.status != Status::Done {
        return Err(invalid(format!(
            "job {reference} is {}: a reference must be done",
            row.status.as_str()
        )));
    }
    let stats: Value = row
        .stats_json
        .as_deref()
        .and_then(|s| serde_json::from_str(s).ok())
        .unwrap_or(Value::Null);
    let dim = |k: &str| {
        stats["params"][k]
            .as_u64()
            .and_then(|v| u32::try_from(v).ok())
    };
    let ref_size = (dim("width"), dim("height"));
    if ref_size != (Some(size.0), Some(size.1)) {
        let shown = |v: Option<u32>| v.map_or("?".to_string(), |v| v.to_string());
        return Err(invalid(format!(
            "job {reference} is {}x{}, this job {}x{}: a reference must have the same width and height",
            shown(ref_size.0),
            shown(ref_size.1),
            size.0,
            size.1
        )));
    }
    Ok(())
}
