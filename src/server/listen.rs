//! The server's own accept loop: hyper's HTTP/1 connections with a cap on their number and a
//! timeout on idle and slow clients. `axum::serve` has neither: a client holding thousands of
//! idle connections, or sending a header byte a second, could exhaust the descriptors and
//! stop the server answering everyone.
//!
//! - **Cap**: a connection takes a permit of a semaphore before it is accepted; at the cap the
//!   loop stops accepting (new connections wait in the kernel's backlog) and the connections
//!   it has go on being served; a permit comes back when a connection ends. The cap is kept
//!   below the process's descriptor limit ([`connection_cap`]), so the store, result files
//!   and render threads always have descriptors left. Reaching it is logged, at most once a
//!   minute.
//! - **Header-read timeout**: hyper arms it whenever a connection waits for a request head,
//!   the first one or the next on a kept-alive connection, so it is the idle timeout too; a
//!   slow sender is closed when its head is not complete in time. Bodies have their own
//!   timeout where they are read (`api::submit_job`).
//! - **Shutdown**: stop accepting, let requests in flight finish (hyper's graceful shutdown;
//!   SSE streams end on the app's own shutdown signal), for at most `drain` time.

use std::future::Future;
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// How the accept loop treats connections (flags of `photonbox serve`).
#[derive(Clone, Debug)]
pub struct ConnLimits {
    /// Connections open at once (further ones wait to be accepted).
    pub max_connections: usize,
    /// Time a client has to send a complete request head, and the longest a kept-alive
    /// connection may sit idle.
    pub header_timeout: Duration,
    /// Time to drain requests in flight at shutdown.
    pub drain: Duration,
}

/// Descriptors kept out of the connections' reach: the store (SQLite and its WAL), result
/// and scene files being written or streamed, the listener, the runtime, stdio.
const RESERVED_FDS: u64 = 128;

/// The connection cap: `requested`, but at most the descriptor limit less a reserve. The soft
/// limit is raised to the hard one first (the usual practice of servers: the soft limit is a
/// default for programs that never asked).
pub fn connection_cap(requested: usize) -> usize {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit/setrlimit on our own process with a valid struct.
    let fds = unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) != 0 {
            return requested;
        }
        if lim.rlim_cur < lim.rlim_max {
            let raised = libc::rlimit {
                rlim_cur: lim.rlim_max,
                rlim_max: lim.rlim_max,
            };
            if libc::setrlimit(libc::RLIMIT_NOFILE, &raised) == 0 {
                lim.rlim_cur = lim.rlim_max;
            }
        }
        lim.rlim_cur
    };
    let room = fds.saturating_sub(RESERVED_FDS).max(16);
    requested.min(usize::try_from(room).unwrap_or(usize::MAX))
}

/// Serve `router` on `listener` until `shutdown` completes.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    limits: ConnLimits,
    shutdown: impl Future<Output = ()>,
) {
    let permits = Arc::new(Semaphore::new(limits.max_connections));
    let graceful = GracefulShutdown::new();
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout);
    let mut last_warning: Option<Instant> = None;
    let mut warn = |msg: String| {
        if last_warning.is_none_or(|t| t.elapsed() > Duration::from_secs(60)) {
            tracing::warn!("{msg}");
            last_warning = Some(Instant::now());
        }
    };
    tokio::pin!(shutdown);
    loop {
        let permit = match permits.clone().try_acquire_owned() {
            Ok(p) => p,
            Err(_) => {
                warn(format!(
                    "{} connections open, the cap: new connections wait until one closes",
                    limits.max_connections
                ));
                tokio::select! {
                    p = permits.clone().acquire_owned() => match p {
                        Ok(p) => p,
                        Err(_) => break,
                    },
                    _ = &mut shutdown => break,
                }
            }
        };
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((stream, _)) => stream,
                Err(e) => {
                    // Out of descriptors despite the cap (another part of the process), or a
                    // connection reset before it was accepted: wait a little, never spin.
                    warn(format!("accepting a connection: {e}"));
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            _ = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let conn = http.serve_connection(
            TokioIo::new(stream),
            TowerToHyperService::new(router.clone()),
        );
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            let _ = conn.await;
            drop(permit);
        });
    }
    drop(listener);
    if tokio::time::timeout(limits.drain, graceful.shutdown())
        .await
        .is_err()
    {
        tracing::warn!("requests still in flight after {:?}: closing", limits.drain);
    }
}
