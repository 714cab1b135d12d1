//! The HTTP API (JSON under /api, bearer tokens), health, metrics and the gallery, as one
//! router. Every API route is registered through utoipa-axum from its handler's
//! `#[utoipa::path]`, so the route and its entry in `GET /api/openapi.json` are one
//! declaration (`openapi.rs` completes the document).

use axum::Json;
use axum::Router;
use axum::extract::{DefaultBodyLimit, State};
use axum::http::header;
use axum::middleware;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::auth::User;
use super::error::ApiError;
use super::extract::PathName;
use super::scenes::SceneCatalog;
use super::state::Snapshot;
use super::store::JobRow;
use super::views::{AuthErrors, ErrorBody, Me, SceneEntry, SceneList};
use super::{AppRef, events, job_routes, metrics, openapi, submit, web};

/// The API's routes, each with its OpenAPI entry.
fn api_routes() -> OpenApiRouter<AppRef> {
    OpenApiRouter::with_openapi(openapi::base())
        .routes(routes!(job_routes::list_jobs, submit::submit_job))
        .routes(routes!(job_routes::get_job, job_routes::delete_job))
        .routes(routes!(job_routes::image))
        .routes(routes!(events::job_events))
        .routes(routes!(list_scenes))
        .routes(routes!(get_scene))
        .routes(routes!(me))
        .routes(routes!(healthz))
        .routes(routes!(metrics_text))
}

/// `GET /api/openapi.json`: the API's document, completed for `catalog`'s scenes (the
/// farm's API instances serve it too: the gallery reads the spec's defaults from it).
pub(crate) fn document(catalog: &SceneCatalog) -> utoipa::openapi::OpenApi {
    openapi::complete(api_routes().split_for_parts().1, &catalog.names())
}

pub fn router(app: AppRef) -> Router {
    let body_limit = app.config.limits.body_bytes;
    let (router, api) = api_routes().split_for_parts();
    let document = openapi::complete(api, &app.catalog.names());
    router
        .route(
            "/api/openapi.json",
            get(move || std::future::ready(Json(document.clone()))),
        )
        .route("/", get(web::index))
        .route("/web/{file}", get(web::web_file))
        .fallback(|| async { ApiError::not_found("route") })
        .method_not_allowed_fallback(|| async { ApiError::method_not_allowed() })
        .layer(DefaultBodyLimit::max(body_limit))
        .layer(middleware::from_fn_with_state(app.clone(), metrics::track))
        .with_state(app)
}

/// Whether `user` may see job `row`: their own, a public one, or any for an admin (the
/// farm's rule too).
pub(crate) fn visible(user: &User, row: &JobRow) -> bool {
    user.admin || row.user_id == user.id || row.public
}

/// A job the user may see (others' private jobs do not exist for them: 404).
pub(super) fn visible_job(
    app: &AppRef,
    user: &User,
    id: i64,
) -> Result<(JobRow, Snapshot), ApiError> {
    match app.jobs.view(id) {
        Some((row, snap)) if visible(user, &row) => Ok((row, snap)),
        _ => Err(ApiError::not_found("job")),
    }
}

/// The user the token belongs to.
#[utoipa::path(get, path = "/api/me", tag = "users", security(("bearer" = [])),
    responses((status = 200, description = "You", body = Me), AuthErrors))]
async fn me(user: User) -> Json<Me> {
    Json(Me {
        id: user.id,
        name: user.name,
        admin: user.admin,
    })
}

/// The built-in scenes.
#[utoipa::path(get, path = "/api/scenes", tag = "scenes", security(("bearer" = [])),
    responses((status = 200, description = "Every built-in scene", body = SceneList), AuthErrors))]
async fn list_scenes(State(app): State<AppRef>, _user: User) -> Json<SceneList> {
    Json(scene_list(&app.catalog))
}

/// The built-in scenes, as `GET /api/scenes` lists them (on the farm too).
pub(crate) fn scene_list(catalog: &SceneCatalog) -> SceneList {
    let scenes = catalog
        .list()
        .into_iter()
        .map(|(name, description)| SceneEntry { name, description })
        .collect();
    SceneList { scenes }
}

/// A built-in scene's JSON, as `GET /api/scenes/{name}` gives it (on the farm too).
pub(crate) fn scene_json(
    catalog: &SceneCatalog,
    name: &str,
) -> Result<Json<serde_json::Value>, ApiError> {
    catalog
        .json(name)
        .cloned()
        .map(Json)
        .ok_or_else(|| ApiError::not_found("scene"))
}

/// A built-in scene's JSON (the scene format: README.md, "Scenes").
#[utoipa::path(get, path = "/api/scenes/{name}", tag = "scenes", security(("bearer" = [])),
    params(("name" = String, Path, description = "The scene's name")),
    responses(
        (status = 200, description = "The scene", body = Object),
        (status = 404, description = "No such scene", body = ErrorBody),
        AuthErrors,
    ))]
async fn get_scene(
    State(app): State<AppRef>,
    _user: User,
    PathName(name): PathName,
) -> Result<Json<serde_json::Value>, ApiError> {
    scene_json(&app.catalog, &name)
}

/// Whether the server answers.
#[utoipa::path(get, path = "/healthz", tag = "operations",
    responses((status = 200, description = "`ok`", body = String, content_type = "text/plain")))]
async fn healthz() -> &'static str {
    "ok\n"
}

/// Prometheus metrics: jobs by status, queue depth, render seconds, the photon-map cache,
/// HTTP requests by route and status.
#[utoipa::path(get, path = "/metrics", tag = "operations",
    responses((status = 200, description = "Prometheus text format", body = String,
        content_type = "text/plain")))]
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The busy 503 of a job submission is documented with its `Retry-After` header (the
    /// server sends it: `error.rs`'s tests), so a client generated from the document can
    /// honour it.
    #[test]
    fn the_busy_503_documents_its_retry_after_header() {
        let catalog = SceneCatalog::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes").into());
        let doc = serde_json::to_value(document(&catalog)).unwrap();
        let busy = &doc["paths"]["/api/jobs"]["post"]["responses"]["503"];
        assert_eq!(
            busy["headers"]["Retry-After"]["schema"]["type"], "integer",
            "{busy}"
        );
    }
}
