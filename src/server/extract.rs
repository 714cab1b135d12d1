//! Extractors: the authenticated user (from the headers alone, so that a request without a
//! valid token is answered 401 before any of its body is read) and a job id from the path
//! (anything that is not one is a 404 in the API's words, never axum's plain-text 400).

use axum::extract::{FromRequestParts, Path};
use axum::http::HeaderMap;
use axum::http::request::Parts;

use super::AppRef;
use super::api::blocking;
use super::auth::{self, User};
use super::error::ApiError;
use super::views::{ImageFile, JobPath};

/// The user a request's bearer token belongs to: its SHA-256 looked up in memory, else in
/// the store on a blocking thread (and remembered: tokens never change).
async fn authenticate(app: &AppRef, headers: &HeaderMap) -> Result<User, ApiError> {
    let hash = auth::token_hash(auth::bearer(headers)?);
    if let Some(u) = app
        .users
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&hash)
    {
        return Ok(u.clone());
    }
    let (app2, hash2) = (app.clone(), hash.clone());
    let user = blocking(move || Ok(app2.store.user_by_token_hash(&hash2)?))
        .await?
        .ok_or_else(ApiError::unauthorized)?;
    app.users
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(hash, user.clone());
    app.user_names
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(user.id, user.name.clone());
    Ok(user)
}

impl FromRequestParts<AppRef> for User {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, app: &AppRef) -> Result<User, ApiError> {
        authenticate(app, &parts.headers).await
    }
}

/// A job id from the path (`{id}`).
impl<S: Send + Sync> FromRequestParts<S> for JobPath {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<JobPath, ApiError> {
        let not_found = || ApiError::not_found("job");
        let Path(id) = Path::<String>::from_request_parts(parts, state)
            .await
            .map_err(|_| not_found())?;
        let id = id.parse().map_err(|_| not_found())?;
        Ok(JobPath { id })
    }
}

/// A name from the path (`{name}`).
pub struct PathName(pub String);

impl<S: Send + Sync> FromRequestParts<S> for PathName {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<PathName, ApiError> {
        Path::<String>::from_request_parts(parts, state)
            .await
            .map(|Path(n)| PathName(n))
            .map_err(|_| ApiError::not_found("name"))
    }
}

/// A job id and one of its image files from the path (`{id}/{file}`).
pub struct JobImage(pub i64, pub ImageFile);

impl<S: Send + Sync> FromRequestParts<S> for JobImage {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<JobImage, ApiError> {
        let Path((id, file)) = Path::<(String, String)>::from_request_parts(parts, state)
            .await
            .map_err(|_| ApiError::not_found("job"))?;
        let id = id.parse().map_err(|_| ApiError::not_found("job"))?;
        let file = ImageFile::parse(&file).ok_or_else(|| ApiError::not_found("file"))?;
        Ok(JobImage(id, file))
    }
}
