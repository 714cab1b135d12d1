//! `GET /api/jobs/{id}/events` on a farm's API instance: the one-box server's events
//! (`status`, `progress`, `preview` for every task done, then `done`, `failed` or
//! `cancelled`; `server::events`), made
//! from the job's row in the store, read every [`EVERY`]. Any instance serves any job's
//! stream; a farm job's progress is its tasks done over its tasks.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::stream::{self, Stream, StreamExt};

use super::api::{FarmApi, job_id, user, visible_job};
use super::epoch_seconds;
use super::snapshot::snapshot;
use crate::server::error::ApiError;
use crate::server::events::diff_events;
use crate::server::state::Snapshot;

/// How often a stream reads its job.
const EVERY: Duration = Duration::from_millis(250);

pub async fn job_events(
    State(api): State<Arc<FarmApi>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let user = user(&api, &headers).await?;
    let id = visible_job(&api, &user, job_id(&id)?).await?.row.id;
    struct St {
        api: Arc<FarmApi>,
        last: Option<Snapshot>,
        ended: bool,
    }
    let st = St {
        api,
        last: None,
        ended: false,
    };
    let events = stream::unfold(st, move |mut st| async move {
        if st.ended {
            return None;
        }
        loop {
            // A job deleted, or a store out of reach, ends the stream.
            let job = st.api.queue.job(id).await.ok().flatten()?;
            let snap = snapshot(&job, epoch_seconds());
            let evs = diff_events(st.last.as_ref(), &snap);
            if !evs.is_empty() {
                st.ended = snap.status.is_final();
                st.last = Some(snap);
                return Some((evs, st));
            }
            tokio::time::sleep(EVERY).await;
        }
    })
    .flat_map(|evs| stream::iter(evs.into_iter().map(Ok)));
    Ok(Sse::new(events).keep_alive(KeepAlive::default()))
}
