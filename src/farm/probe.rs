//! `/healthz` and `/metrics` of every farm process: an API instance answers them beside its
//! routes, a worker started with `--addr` answers them alone (the Docker image's
//! HEALTHCHECK asks every container the same `/healthz`).

use std::sync::atomic::{AtomicBool, Ordering};

use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio::sync::watch;

use super::{FarmError, Queue};

/// Healthy when the store answers.
pub async fn health(queue: &Queue) -> Response {
    match sqlx::query("SELECT 1").execute(queue.pool()).await {
        Ok(_) => {
            store_answered();
            "ok\n".into_response()
        }
        Err(e) => store_unavailable(&e),
    }
}

/// Whether this process's last probe found the store away. A probe logs when that changes,
/// not at every call: a load balancer asking every few seconds through an outage would
/// otherwise fill the log with the same line.
static STORE_AWAY: AtomicBool = AtomicBool::new(false);

/// Records whether the store answered; true when that differs from the last probe's.
fn store_changed(away: &AtomicBool, now_away: bool) -> bool {
    away.swap(now_away, Ordering::Relaxed) != now_away
}

fn store_answered() {
    if store_changed(&STORE_AWAY, false) {
        tracing::info!("probe: the store answers again");
    }
}

/// 503 for an unauthenticated probe whose store failed: the store's error (its address,
/// its user) goes to the log, once an outage, not to whoever asked.
fn store_unavailable(e: &dyn std::fmt::Display) -> Response {
    if store_changed(&STORE_AWAY, true) {
        tracing::warn!("probe: the store: {e} (not logged again until it answers)");
    }
    (StatusCode::SERVICE_UNAVAILABLE, "store unavailable\n").into_response()
}

/// This process's queue counters, the farm's counters and the queue's depth (Prometheus
/// text; unauthenticated, like one box's, so nothing in it names or numbers a user).
pub async fn metrics(queue: &Queue) -> Response {
    match metrics_text(queue).await {
        Ok(out) => {
            store_answered();
            ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], out).into_response()
        }
        Err(e) => store_unavailable(&e),
    }
}

async fn metrics_text(queue: &Queue) -> Result<String, FarmError> {
    let m = queue.metrics();
    let mut out = String::new();
    let mut line = |kind: &str, name: &str, help: &str, v: i64| {
        out += &format!("# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {v}\n");
    };
    let as_i64 = |v: u64| i64::try_from(v).unwrap_or(i64::MAX);
    line(
        "counter",
        "photonbox_farm_tasks_claimed_total",
        "Tasks this process claimed.",
        as_i64(m.claimed()),
    );
    line(
        "counter",
        "photonbox_farm_leases_expired_total",
        "Expired leases this process reaped.",
        as_i64(m.leases_expired()),
    );
    line(
        "counter",
        "photonbox_farm_fenced_results_refused_total",
        "Results this process handed in that a newer attempt had fenced off.",
        as_i64(m.fenced_refused()),
    );
    let (expired, fenced) = farm_counters(queue).await?;
    line(
        "counter",
        "photonbox_farm_store_leases_expired_total",
        "Expired leases reaped, by every process of the farm.",
        expired,
    );
    line(
        "counter",
        "photonbox_farm_store_fenced_results_refused_total",
        "Stale results refused, from every worker of the farm.",
        fenced,
    );
    let depth = queue.queue_depth().await?;
    let mut gauge = |name: &str, help: &str, v: i64| {
        out += &format!("# HELP {name} {help}\n# TYPE {name} gauge\n{name} {v}\n");
    };
    gauge("photonbox_farm_queued_tasks", "Queued tasks.", depth.tasks);
    gauge(
        "photonbox_farm_queued_users",
        "Users with queued tasks.",
        depth.users,
    );
    Ok(out)
}

/// The farm-wide counters in the store: (expired leases, fenced results refused).
async fn farm_counters(queue: &Queue) -> Result<(i64, i64), FarmError> {
    let get = |name: &'static str| {
        sqlx::query_scalar::<_, i64>("SELECT n FROM counters WHERE name = $1").bind(name)
    };
    Ok((
        get("leases_expired").fetch_one(queue.pool()).await?,
        get("fenced_refused").fetch_one(queue.pool()).await?,
    ))
}

/// A worker's probes: 503 until it has joined the farm (`joined` holds its queue then).
pub fn worker_router(joined: watch::Receiver<Option<Queue>>) -> Router {
    Router::new()
        .route("/healthz", get(worker_health))
        .route("/metrics", get(worker_metrics))
        .with_state(joined)
}

fn joining() -> Response {
    (StatusCode::SERVICE_UNAVAILABLE, "joining the farm\n").into_response()
}

async fn worker_health(State(joined): State<watch::Receiver<Option<Queue>>>) -> Response {
    let queue = joined.borrow().clone();
    match queue {
        Some(q) => health(&q).await,
        None => joining(),
    }
}

async fn worker_metrics(State(joined): State<watch::Receiver<Option<Queue>>>) -> Response {
    let queue = joined.borrow().clone();
    match queue {
        Some(q) => metrics(&q).await,
        None => joining(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An outage is logged when it starts and when it ends, not at every probe between.
    #[test]
    fn a_probe_logs_only_when_the_store_comes_or_goes() {
        let away = AtomicBool::new(false);
        let probes = [false, true, true, true, false, false, true];
        let logged: Vec<bool> = probes.iter().map(|&a| store_changed(&away, a)).collect();
        assert_eq!(logged, [false, true, false, false, true, false, true]);
    }
}
