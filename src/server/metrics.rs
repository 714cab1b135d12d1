//! Prometheus text-format metrics: jobs by status, queue depth, render seconds, photon-map
//! cache hits/misses/bytes, HTTP requests by route and status.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::Ordering;

use axum::extract::{MatchedPath, Request, State};
use axum::middleware::Next;
use axum::response::Response;

use super::AppRef;

#[derive(Default)]
pub struct Metrics {
    /// Keyed by (method, route template, status): every part from a small closed set (see
    /// [`method_label`]; routes are the router's templates or "unmatched"), so no client can
    /// grow this map.
    http: Mutex<BTreeMap<(&'static str, String, u16), u64>>,
    render_seconds: Mutex<f64>,
}

impl Metrics {
    pub fn add_render_seconds(&self, s: f64) {
        *self
            .render_seconds
            .lock()
            .unwrap_or_else(|e| e.into_inner()) += s;
    }

    fn record(&self, method: &'static str, route: &str, status: u16) {
        let mut http = self.http.lock().unwrap_or_else(|e| e.into_inner());
        match http.get_mut(&(method, route.to_string(), status)) {
            Some(n) => *n += 1,
            None => {
                http.insert((method, route.to_string(), status), 1);
            }
        }
    }
}

/// Middleware: count every request by method, matched route and status.
pub async fn track(State(app): State<AppRef>, req: Request, next: Next) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or("unmatched", |m| m.as_str())
        .to_string();
    let method = method_label(req.method());
    let resp = next.run(req).await;
    app.metrics.record(method, &route, resp.status().as_u16());
    resp
}

/// A request method as a metric label: the standard methods by name, anything else (any
/// token is a valid HTTP method) as "other".
fn method_label(m: &axum::http::Method) -> &'static str {
    use axum::http::Method;
    const KNOWN: [(Method, &str); 9] = [
        (Method::GET, "GET"),
        (Method::HEAD, "HEAD"),
        (Method::POST, "POST"),
        (Method::PUT, "PUT"),
        (Method::DELETE, "DELETE"),
        (Method::OPTIONS, "OPTIONS"),
        (Method::PATCH, "PATCH"),
        (Method::TRACE, "TRACE"),
        (Method::CONNECT, "CONNECT"),
    ];
    KNOWN
        .iter()
        .find(|(k, _)| k == m)
        .map_or("other", |(_, name)| name)
}

/// One metric family with a single unlabelled sample.
fn family(s: &mut String, name: &str, kind: &str, help: &str, value: impl std::fmt::Display) {
    let _ = writeln!(
        s,
        "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {value}"
    );
}

pub fn render(app: &super::App) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# HELP photonbox_jobs Jobs by status.\n# TYPE photonbox_jobs gauge"
    );
    for (status, n) in app.jobs.count_by_status() {
        let _ = writeln!(s, "photonbox_jobs{{status=\"{status}\"}} {n}");
    }
    family(
        &mut s,
        "photonbox_queue_depth",
        "gauge",
        "Jobs waiting to start.",
        app.scheduler.queue_depth(),
    );
    let secs = *app
        .metrics
        .render_seconds
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    family(
        &mut s,
        "photonbox_render_seconds_total",
        "counter",
        "Wall-clock seconds spent running jobs.",
        secs,
    );
    let c = &app.cache;
    family(
        &mut s,
        "photonbox_photon_map_cache_hits_total",
        "counter",
        "Jobs that reused cached photon maps.",
        c.hits.load(Ordering::Relaxed),
    );
    family(
        &mut s,
        "photonbox_photon_map_cache_misses_total",
        "counter",
        "Jobs that traced their photon maps.",
        c.misses.load(Ordering::Relaxed),
    );
    family(
        &mut s,
        "photonbox_photon_map_cache_bytes",
        "gauge",
        "Bytes of photon maps held by the cache.",
        c.bytes(),
    );
    if let Some(bytes) = heap_in_use() {
        family(
            &mut s,
            "photonbox_heap_in_use_bytes",
            "gauge",
            "Heap bytes allocated and not freed (glibc's count): what the server holds, apart \
             from what its allocator keeps free for reuse (resident, but not held).",
            bytes,
        );
    }
    let _ = writeln!(
        s,
        "# HELP photonbox_http_requests_total HTTP requests by method, route and status.\n# TYPE photonbox_http_requests_total counter"
    );
    let http = app.metrics.http.lock().unwrap_or_else(|e| e.into_inner());
    for ((method, route, status), n) in http.iter() {
        let _ = writeln!(
            s,
            "photonbox_http_requests_total{{method=\"{method}\",route=\"{route}\",status=\"{status}\"}} {n}"
        );
    }
    s
}

/// Heap bytes in use, as glibc counts them (small and mmapped blocks).
fn heap_in_use() -> Option<u64> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallinfo2 only reads the allocator's counters.
        let info = unsafe { libc::mallinfo2() };
        Some((info.uordblks + info.hblkhd) as u64)
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    None
}
