//! API errors: an HTTP status and a JSON body `{"error": ..., "path": ...}` that names the
//! offending field (a JSON path into the request, a header, or a limit).

use axum::Json;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::views::ErrorBody;

#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub message: String,
    pub path: Option<String>,
    /// A 5xx whose message is the client's to read (`ApiError::busy`); every other 5xx's
    /// detail is the operator's.
    told: bool,
    /// Seconds after which a retry may succeed (the `Retry-After` header of a busy 503).
    retry_after: Option<u32>,
}

impl ApiError {
    pub fn new(status: StatusCode, path: Option<&str>, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            message: message.into(),
            path: path.map(str::to_string),
            told: false,
            retry_after: None,
        }
    }

    /// 422: a well-formed request whose value at `path` is unacceptable.
    pub fn invalid(path: impl Into<String>, message: impl Into<String>) -> ApiError {
        ApiError {
            status: StatusCode::UNPROCESSABLE_ENTITY,
            message: message.into(),
            path: Some(path.into()),
            told: false,
            retry_after: None,
        }
    }

    pub fn not_found(what: &str) -> ApiError {
        ApiError::new(StatusCode::NOT_FOUND, None, format!("{what} not found"))
    }

    pub fn unauthorized() -> ApiError {
        ApiError::new(
            StatusCode::UNAUTHORIZED,
            Some("header.Authorization"),
            "missing or invalid token: send `Authorization: Bearer TOKEN`",
        )
    }

    pub fn internal(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, None, message)
    }

    /// 503 that says what to do (try again later), shown to the client as it is.
    pub fn busy(path: &str, retry_after: u32, message: impl Into<String>) -> ApiError {
        ApiError {
            told: true,
            retry_after: Some(retry_after),
            ..ApiError::new(StatusCode::SERVICE_UNAVAILABLE, Some(path), message)
        }
    }

    /// 405 on a route that exists (axum adds the `Allow` header).
    pub fn method_not_allowed() -> ApiError {
        ApiError::new(
            StatusCode::METHOD_NOT_ALLOWED,
            None,
            "this route does not take that method (the Allow header lists those it takes)",
        )
    }
}

/// The most of a message, or of a path, that goes back to a client (then a note of how
/// much was cut): errors quote what the client sent (a scene's name, a key, a value),
/// which may be megabytes.
const MAX_ECHO: usize = 1024;

/// `s` cut to [`MAX_ECHO`] bytes (at a character boundary), saying how much was cut.
fn bounded(mut s: String) -> String {
    if s.len() > MAX_ECHO {
        let end = (0..=MAX_ECHO).rev().find(|&i| s.is_char_boundary(i));
        let end = end.unwrap_or(0);
        let cut = s.len() - end;
        s.truncate(end);
        s.push_str(&format!("... ({cut} more bytes)"));
    }
    s
}

impl IntoResponse for ApiError {
    /// User errors (and `busy`) keep their status, message and path. Internal errors are
    /// logged once, here, with a request id, and the client gets only the id: their detail
    /// (paths, SQL) is the operator's, not the client's.
    fn into_response(self) -> Response {
        if self.status.is_server_error() && !self.told {
            let id = super::auth::new_token()[..12].to_string();
            tracing::error!(request_id = id, "{}", self.message);
            let body = ErrorBody {
                error: format!("internal error (request {id}: see the server's log)"),
                path: None,
                request_id: Some(id),
            };
            return (self.status, Json(body)).into_response();
        }
        let body = ErrorBody {
            error: bounded(self.message),
            path: self.path.map(bounded),
            request_id: None,
        };
        let mut response = (self.status, Json(body)).into_response();
        if let Some(secs) = self.retry_after {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(secs));
        }
        response
    }
}

impl From<super::scenes::SceneRefError> for ApiError {
    fn from(e: super::scenes::SceneRefError) -> ApiError {
        match e {
            super::scenes::SceneRefError::Invalid { path, message } => {
                ApiError::invalid(path, message)
            }
            super::scenes::SceneRefError::Internal(m) => ApiError::internal(m),
        }
    }
}

impl From<rusqlite::Error> for ApiError {
    fn from(e: rusqlite::Error) -> ApiError {
        ApiError::internal(format!("store: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(e: ApiError) -> (u16, serde_json::Value) {
        let resp = e.into_response();
        let status = resp.status().as_u16();
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let bytes = rt
            .block_on(axum::body::to_bytes(resp.into_body(), 1 << 24))
            .unwrap();
        (status, serde_json::from_slice(&bytes).unwrap())
    }

    #[test]
    fn internal_errors_hide_their_detail_behind_a_request_id() {
        let (status, v) = body(ApiError::internal(
            "store: /srv/data/photonbox.sqlite3 is locked",
        ));
        assert_eq!(status, 500);
        let text = v.to_string();
        assert!(
            !text.contains("sqlite3") && !text.contains("store"),
            "{text}"
        );
        let id = v["request_id"].as_str().unwrap();
        assert_eq!(id.len(), 12);
        assert!(v["error"].as_str().unwrap().contains(id));
    }

    #[test]
    fn user_errors_keep_their_message_and_path() {
        let (status, v) = body(ApiError::invalid("params.k", "k must be at least 1"));
        assert_eq!(status, 422);
        assert_eq!(v["path"], "params.k");
        assert_eq!(v["error"], "k must be at least 1");
    }

    #[test]
    fn only_a_busy_503_shows_its_message() {
        let store = ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            None,
            "the store: connection to 10.0.0.5 refused",
        );
        let (status, v) = body(store);
        assert_eq!(status, 503);
        assert!(!v.to_string().contains("10.0.0.5"), "{v}");
        let busy = || ApiError::busy("body", 5, "try again shortly");
        assert_eq!(busy().into_response().headers()[header::RETRY_AFTER], "5");
        let (status, v) = body(busy());
        assert_eq!(
            (status, v["error"].as_str()),
            (503, Some("try again shortly"))
        );
    }

    #[test]
    fn what_a_client_sent_is_echoed_at_most_a_kilobyte() {
        let long = "é".repeat(300_000);
        let (status, v) = body(ApiError::invalid(
            format!("params.{long}"),
            format!("no built-in scene named {long:?}"),
        ));
        assert_eq!(status, 422);
        let (error, path) = (v["error"].as_str().unwrap(), v["path"].as_str().unwrap());
        assert!(error.len() < 1100 && path.len() < 1100, "{}", error.len());
        assert!(error.starts_with("no built-in scene named \"éé"), "{error}");
        assert!(error.ends_with(" more bytes)"), "{error}");
    }
}
