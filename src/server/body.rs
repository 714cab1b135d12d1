//! Request bodies within bounds: their size (413, before reading when the length is
//! declared), their time (408), and the memory of their parsing. Parsed into JSON and
//! admitted, a body takes about ten times its bytes (a 16 MB uploaded scene: 150-170 MB,
//! docs/security.md), and thousands of connections may send one at once; so the bytes of
//! bodies being read and admitted at once share a budget of four of the largest, and a
//! request waits its turn (at most the body timeout, then 503). A user has one large body
//! in admission at a time, so that one user's slow uploads cannot hold the whole budget.
//! Small bodies (64 KiB, declared) go without: a job on a built-in scene never waits
//! behind uploads.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::body::Body;
use axum::http::{HeaderMap, StatusCode, header};
use serde_json::Value;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use super::error::ApiError;

/// Reads request bodies for every front end (one box and the farm).
pub(crate) struct BodyReader {
    limit: usize,
    timeout: Duration,
    /// KiB of bodies being read or admitted at once.
    budget: Arc<Semaphore>,
    budget_kib: u32,
    /// Each user's turn for a large body (one permit a user).
    turns: Mutex<HashMap<i64, Arc<Semaphore>>>,
}

/// A request's body, parsed, and its share of the budget (none for a small body): hold it
/// until the request is admitted or refused.
pub(crate) struct ReadBody {
    pub value: Value,
    pub share: Option<Share>,
}

/// A large body's turn among its user's and its bytes of the budget.
pub(crate) struct Share {
    _turn: OwnedSemaphorePermit,
    _bytes: OwnedSemaphorePermit,
}

/// How many users' turns the reader keeps before it forgets the idle ones.
const PRUNE_TURNS_AT: usize = 64;

/// Bodies of the largest size that may be in admission at once.
const LARGEST_AT_ONCE: usize = 4;

/// What a request refused for want of budget is told to wait before it tries again.
const RETRY_AFTER_SECS: u32 = 5;

/// Bodies declared this small go without a share: large ones waiting for theirs do not
/// hold up a job on a built-in scene.
const SMALL: u64 = 64 << 10;

impl BodyReader {
    pub fn new(limit: usize, timeout: Duration) -> BodyReader {
        let budget = LARGEST_AT_ONCE.saturating_mul(limit).div_ceil(1024).max(1);
        let budget_kib = u32::try_from(budget).unwrap_or(u32::MAX);
        BodyReader {
            limit,
            timeout,
            budget: Arc::new(Semaphore::new(budget_kib as usize)),
            budget_kib,
            turns: Mutex::default(),
        }
    }

    /// User `user`'s request body as a JSON object, read within the size limit and the
    /// timeout once the budget holds its declared length (else the limit), unless it is
    /// small.
    pub async fn read(
        &self,
        user: i64,
        headers: &HeaderMap,
        body: Body,
    ) -> Result<ReadBody, ApiError> {
        let limit = self.limit;
        let too_large = || {
            ApiError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                Some("body"),
                format!("request body larger than the limit of {limit} bytes"),
            )
        };
        let declared = headers
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse::<u64>().ok());
        if declared.is_some_and(|n| n > limit as u64) {
            return Err(too_large());
        }
        let share = match declared {
            Some(n) if n <= SMALL => None,
            _ => Some(
                self.share(user, declared.map_or(limit, |n| n as usize))
                    .await?,
            ),
        };
        let read = tokio::time::timeout(self.timeout, axum::body::to_bytes(body, limit));
        let body = read.await.map_err(|_| {
            ApiError::new(
                StatusCode::REQUEST_TIMEOUT,
                Some("body"),
                format!(
                    "the request body did not arrive within {} s",
                    self.timeout.as_secs_f64()
                ),
            )
        })?;
        let body = body.map_err(|e| match over_limit(&e) {
            true => too_large(),
            false => ApiError::new(
                StatusCode::BAD_REQUEST,
                Some("body"),
                format!("reading the body: {e}"),
            ),
        })?;
        let bad = |m: String| ApiError::new(StatusCode::BAD_REQUEST, Some("body"), m);
        let value: Value =
            serde_json::from_slice(&body).map_err(|e| bad(format!("malformed JSON: {e}")))?;
        if !value.is_object() {
            return Err(bad("expected a JSON object".into()));
        }
        Ok(ReadBody { value, share })
    }

    /// User `user`'s turns (a semaphore of one permit, made at their first large body).
    fn turn_of(&self, user: i64) -> Arc<Semaphore> {
        let mut turns = self.turns.lock().unwrap_or_else(|e| e.into_inner());
        if turns.len() >= PRUNE_TURNS_AT && !turns.contains_key(&user) {
            // A turn nobody holds or waits for is only this map's (its permit holders and
            // waiters hold clones): forget it, so the map holds the users of the moment.
            turns.retain(|_, t| Arc::strong_count(t) > 1);
        }
        let turn = turns
            .entry(user)
            .or_insert_with(|| Arc::new(Semaphore::new(1)));
        turn.clone()
    }

    /// User `user`'s turn and a share of the budget for a body of `bytes`, waited for at
    /// most the body timeout.
    async fn share(&self, user: i64, bytes: usize) -> Result<Share, ApiError> {
        let kib = u32::try_from(bytes.div_ceil(1024).max(1)).unwrap_or(u32::MAX);
        let turn = self.turn_of(user);
        let wait = async {
            let turn = turn.acquire_owned().await?;
            let bytes = self.budget.clone();
            let bytes = bytes.acquire_many_owned(kib.min(self.budget_kib)).await?;
            Ok::<_, tokio::sync::AcquireError>(Share {
                _turn: turn,
                _bytes: bytes,
            })
        };
        match tokio::time::timeout(self.timeout, wait).await {
            Ok(Ok(share)) => Ok(share),
            _ => Err(ApiError::busy(
                "body",
                RETRY_AFTER_SECS,
                "the server is reading as many large requests as it takes at once (one of \
                 each user's at a time): try again shortly",
            )),
        }
    }
}

/// Whether reading a body failed because it passed the limit.
fn over_limit(e: &axum::Error) -> bool {
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = source {
        if err.is::<http_body_util::LengthLimitError>() {
            return true;
        }
        source = err.source();
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The turns of users who have no body in admission are forgotten once there are
    /// many; a turn someone holds is kept (its holder would otherwise share it with a
    /// newcomer's fresh one).
    #[test]
    fn idle_users_turns_are_forgotten_and_held_ones_kept() {
        let reader = BodyReader::new(1 << 20, Duration::from_secs(1));
        let held = reader.turn_of(-1);
        for user in 0..1000 {
            reader.turn_of(user);
        }
        let turns = reader.turns.lock().unwrap();
        assert!(turns.len() <= PRUNE_TURNS_AT, "{} turns kept", turns.len());
        assert!(Arc::ptr_eq(&turns[&-1], &held));
    }
}
