//! A finished job's image out of the store, as one box's file server answers it: streamed in
//! slices (the API instance never holds the whole file: a 4096x4096 EXR is 130 MB, and
//! several downloads at once would be several of them), with a single `Range` (206, or 416
//! with the length when it cannot be met) and `Accept-Ranges`. `HEAD` reads only the
//! length: axum drops the body unpolled.

use axum::body::{Body, Bytes};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

use super::Queue;
use super::api::store_error;
use crate::server::error::ApiError;

/// Bytes read from the store at a time.
const SLICE: u64 = 1 << 20;

/// The response for job `id`'s final image (`exr` or `png`), None if it has none.
pub(super) async fn final_image(
    queue: &Queue,
    id: i64,
    exr: bool,
    mime: &'static str,
    headers: &HeaderMap,
) -> Result<Option<Response>, ApiError> {
    let Some(len) = queue.job_image_len(id, exr).await.map_err(store_error)? else {
        return Ok(None);
    };
    // A Range with If-Range asks for the range only if the file is unchanged; we give no
    // validators to compare, so such a request gets the whole file (RFC 9110, 13.1.5).
    let asked = match headers.get(header::RANGE) {
        Some(r) if headers.get(header::IF_RANGE).is_none() => Some(r),
        _ => None,
    };
    let range = match asked.map(|r| satisfiable(r, len)) {
        Some(Some(r)) => Some(r),
        Some(None) => {
            let unmet = format!("bytes */{len}");
            return Ok(Some(
                (
                    StatusCode::RANGE_NOT_SATISFIABLE,
                    [(header::CONTENT_RANGE, unmet)],
                )
                    .into_response(),
            ));
        }
        None => None,
    };
    let (start, end) = range.unwrap_or((0, len));
    let queue = queue.clone();
    // Each step reads the next slice; a failure ends the body early (the client sees a
    // short read against Content-Length) and the stream.
    let slices = futures_util::stream::unfold(start, move |at| {
        let queue = queue.clone();
        async move {
            if at >= end {
                return None;
            }
            let n = (end - at).min(SLICE);
            let read = match queue.job_image_part(id, exr, at, n).await {
                Ok(Some(bytes)) if bytes.len() as u64 == n => Ok(Bytes::from(bytes)),
                Ok(_) => Err(std::io::Error::other("the image is gone")),
                Err(e) => Err(std::io::Error::other(e.to_string())),
            };
            let next = if read.is_ok() { at + n } else { end };
            Some((read, next))
        }
    });
    let mut response = Body::from_stream(slices).into_response();
    let h = response.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(mime));
    h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(end - start));
    if range.is_some() {
        let what = format!("bytes {start}-{}/{len}", end - 1);
        h.insert(
            header::CONTENT_RANGE,
            HeaderValue::from_str(&what).expect("digits"),
        );
        *response.status_mut() = StatusCode::PARTIAL_CONTENT;
    }
    Ok(Some(response))
}

/// The byte range `start..end` a `Range` header asks of a file of `len` bytes, if it is one
/// range this file can meet (`bytes=a-b`, `bytes=a-`, `bytes=-n`); None otherwise
/// (malformed, several ranges, or past the end), which is a 416.
fn satisfiable(value: &HeaderValue, len: u64) -> Option<(u64, u64)> {
    let spec = value.to_str().ok()?.trim().strip_prefix("bytes=")?;
    let (a, b) = spec.trim().split_once('-')?;
    let number = |s: &str| -> Option<u64> {
        let s = s.trim();
        (!s.is_empty() && s.bytes().all(|c| c.is_ascii_digit()))
            .then(|| s.parse().ok())
            .flatten()
    };
    let (start, end) = match (a.trim().is_empty(), b.trim().is_empty()) {
        // The last n bytes.
        (true, false) => {
            let n = number(b)?.min(len);
            (len - n, len)
        }
        (false, true) => (number(a)?, len),
        (false, false) => (number(a)?, number(b)?.saturating_add(1).min(len)),
        (true, true) => return None,
    };
    (start < end && start < len).then_some((start, end))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_read_as_one_box_s_file_server_reads_them() {
        let r = |s: &str| satisfiable(&HeaderValue::from_str(s).unwrap(), 100);
        assert_eq!(r("bytes=0-10"), Some((0, 11)));
        assert_eq!(r("bytes=90-"), Some((90, 100)));
        assert_eq!(r("bytes=-5"), Some((95, 100)));
        assert_eq!(r("bytes=-500"), Some((0, 100)));
        assert_eq!(r("bytes=50-5000"), Some((50, 100)));
        for bad in [
            "bytes=5-1",
            "bytes=100-",
            "bytes=abc",
            "bytes=-0",
            "bytes=0-1,5-6",
            "items=0-1",
            "bytes=-",
            "bytes=+1-2",
        ] {
            assert_eq!(r(bad), None, "{bad}");
        }
    }
}
