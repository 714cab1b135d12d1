//! `GET /api/jobs/{id}/events`: a job's progress as server-sent events, from its `watch`
//! channel. A late client first gets the current state; the stream ends after the final
//! event, or when the server shuts down.

use std::convert::Infallible;

use axum::extract::State;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::stream::{self, Stream, StreamExt};

use super::AppRef;
use super::api::visible_job;
use super::auth::User;
use super::error::ApiError;
use super::state::Snapshot;
use super::views::{JobErrors, JobPath};

/// SSE: `status`, `progress`, `preview`, then one final `done|failed|cancelled`. A client
/// that connects late first gets the current status and progress.
#[utoipa::path(get, path = "/api/jobs/{id}/events", tag = "jobs", security(("bearer" = [])),
    params(JobPath),
    responses(
        (status = 200, description = "Server-sent events: `status`, `progress`, `preview`, \
            then `done`, `failed` or `cancelled`; each event's data is the job's live state \
            (status, progress, phase, eta_seconds, previews, error)",
            content_type = "text/event-stream"),
        JobErrors,
    ))]
pub async fn job_events(
    State(app): State<AppRef>,
    user: User,
    JobPath { id }: JobPath,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let (row, _) = visible_job(&app, &user, id)?;
    let live = app
        .jobs
        .live(row.id)
        .ok_or_else(|| ApiError::not_found("job"))?;
    let rx = live.subscribe();
    drop(live);
    let shutdown = app.shutdown.subscribe();
    struct St {
        rx: tokio::sync::watch::Receiver<Snapshot>,
        shutdown: tokio::sync::watch::Receiver<bool>,
        last: Option<Snapshot>,
        ended: bool,
    }
    let st = St {
        rx,
        shutdown,
        last: None,
        ended: false,
    };
    let events = stream::unfold(st, |mut st| async move {
        if st.ended {
            return None;
        }
        loop {
            if *st.shutdown.borrow() {
                return None;
            }
            let snap = st.rx.borrow_and_update().clone();
            let evs = diff_events(st.last.as_ref(), &snap);
            if !evs.is_empty() {
                st.ended = snap.status.is_final();
                st.last = Some(snap);
                return Some((evs, st));
            }
            tokio::select! {
                r = st.rx.changed() => if r.is_err() { return None; },
                _ = st.shutdown.changed() => return None,
            }
        }
    })
    .flat_map(|evs| stream::iter(evs.into_iter().map(Ok)));
    Ok(Sse::new(events).keep_alive(KeepAlive::default()))
}

fn event(name: &str, snap: &Snapshot) -> Event {
    Event::default()
        .event(name)
        .data(serde_json::to_string(snap).unwrap_or_default())
}

/// The events that take a client from `last` to `now` (the farm's stream too).
pub(crate) fn diff_events(last: Option<&Snapshot>, now: &Snapshot) -> Vec<Event> {
    let mut out = Vec::new();
    if last.is_none_or(|l| l.status != now.status) {
        out.push(event("status", now));
    }
    if last.is_none_or(|l| l.progress != now.progress || l.phase != now.phase) {
        out.push(event("progress", now));
    }
    if last.map_or(now.previews > 0, |l| now.previews > l.previews) {
        out.push(event("preview", now));
    }
    if now.status.is_final() {
        out.push(event(now.status.as_str(), now));
    }
    out
}
