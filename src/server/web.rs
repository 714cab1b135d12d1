//! The gallery (web/): static files embedded in the binary, so a newcomer needs no build
//! step and the server nothing beside itself. The page is a client of the public API and
//! nothing more (ARCHITECTURE.md).

use axum::extract::Path;
use axum::http::header;
use axum::response::{Html, IntoResponse, Response};

use super::error::ApiError;

/// The scripts are native ES modules: app.js imports the others by relative URL, so each
/// needs its entry here. (file name, content type, content)
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

pub async fn index() -> Response {
    (
        [(header::CONTENT_SECURITY_POLICY, CSP)],
        Html(include_str!("../../web/index.html")),
    )
        .into_response()
}

pub async fn web_file(Path(file): Path<String>) -> Result<Response, ApiError> {
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
