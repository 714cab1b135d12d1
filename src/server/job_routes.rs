//! `/api/jobs/...`: list, show, cancel or delete jobs, and download their images. (Submit:
//! `submit.rs`; SSE: `events.rs`.)

use std::time::Duration;

use axum::Json;
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use tower::ServiceExt;
use tower_http::services::ServeFile;

use super::AppRef;
use super::api::{blocking, visible, visible_job};
use super::auth::User;
use super::error::ApiError;
use super::extract::JobImage;
use super::results::{remove_results, result_path};
use super::store::{JobRow, Status, now};
use super::views::{
    AuthErrors, ErrorBody, ImageFile, JobErrors, JobList, JobPath, JobView, Stopped,
};

/// A job as the user sees it.
fn view(app: &AppRef, user: &User, row: &JobRow, snap: &super::state::Snapshot) -> JobView {
    JobView::of(
        row,
        snap,
        app.user_name(row.user_id),
        row.user_id == user.id,
    )
}

/// Your jobs and the public ones (an admin: every job), newest first.
#[utoipa::path(get, path = "/api/jobs", tag = "jobs", security(("bearer" = [])),
    responses((status = 200, description = "The jobs", body = JobList), AuthErrors))]
pub async fn list_jobs(State(app): State<AppRef>, user: User) -> Json<JobList> {
    let positions = app.scheduler.queue_positions();
    let jobs = app
        .jobs
        .list(|r| visible(&user, r))
        .iter()
        .map(|(row, snap)| JobView {
            queue_position: positions.get(&row.id).copied(),
            ..view(&app, &user, row, snap)
        })
        .collect();
    Json(JobList { jobs })
}

/// A job: status, progress, phase, ETA, and its stats once done.
#[utoipa::path(get, path = "/api/jobs/{id}", tag = "jobs", security(("bearer" = [])),
    params(JobPath), responses((status = 200, description = "The job", body = JobView), JobErrors))]
pub async fn get_job(
    State(app): State<AppRef>,
    user: User,
    JobPath { id }: JobPath,
) -> Result<Json<JobView>, ApiError> {
    let (row, snap) = visible_job(&app, &user, id)?;
    Ok(Json(JobView {
        queue_position: app.scheduler.queue_position(row.id),
        ..view(&app, &user, &row, &snap)
    }))
}

/// Cancel a queued or running job; delete a finished one (and its images).
#[utoipa::path(delete, path = "/api/jobs/{id}", tag = "jobs", security(("bearer" = [])),
    params(JobPath),
    responses(
        (status = 200, description = "Asked to stop: whether it has", body = Stopped),
        (status = 204, description = "A finished job, deleted"),
        (status = 403, description = "Another user's public job", body = ErrorBody),
        (status = 409, description = "The job is starting: try again", body = ErrorBody),
        JobErrors,
    ))]
pub async fn delete_job(
    State(app): State<AppRef>,
    user: User,
    JobPath { id }: JobPath,
) -> Result<Response, ApiError> {
    let (row, _) = visible_job(&app, &user, id)?;
    if !(user.admin || row.user_id == user.id) {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            None,
            "this public job is read-only for you",
        ));
    }
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
        let status = Status::Cancelled;
        return Ok(Json(Stopped { id, status }).into_response());
    }
    if app.scheduler.cancel_running(id) {
        // Wait (briefly) until the render has stopped and released its memory.
        if let Some(live) = app.jobs.live(id) {
            let mut rx = live.subscribe();
            let stopped = rx.wait_for(|s| s.status.is_final() || s.status == Status::Queued);
            let _ = tokio::time::timeout(Duration::from_secs(5), stopped).await;
        }
        let status = app.jobs.row(id).map_or(Status::Cancelled, |r| r.status);
        return Ok(Json(Stopped { id, status }).into_response());
    }
    // Between queue and pool (a race with the dispatcher): the client may retry.
    Err(ApiError::new(
        StatusCode::CONFLICT,
        None,
        "the job is starting; try again",
    ))
}

/// A job's image: the final one, or the latest preview while a progressive job runs.
/// Streamed from the file (tower-http's `ServeFile`: chunks, not the whole file in memory),
/// with `Range` (but on a preview), conditional requests and a cheap `HEAD` (axum answers it
/// from the same handler without a body). A preview replaced meanwhile (by a rename) does not
/// disturb a download in flight: it reads the file it opened.
#[utoipa::path(get, path = "/api/jobs/{id}/{file}", tag = "jobs", security(("bearer" = [])),
    params(JobPath, ("file" = inline(ImageFile), Path, description = "Which image")),
    responses(
        (status = 200, description = "The image",
            content(("image/png"), ("image/x-exr"))),
        (status = 404, description = "No such job that you may see, or no image yet",
            body = ErrorBody),
        AuthErrors,
    ))]
pub async fn image(
    State(app): State<AppRef>,
    user: User,
    JobImage(id, file): JobImage,
    mut req: Request,
) -> Result<Response, ApiError> {
    let (ext, mime) = file.ext_and_type();
    let (row, _) = visible_job(&app, &user, id)?;
    let path = result_path(&app.config.data, row.id, ext);
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
