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
//! - **Write timeout**: a response write that makes no progress for `write_timeout` (a
//!   client that stopped reading: an SSE stream or a download it never drains, pipelined
//!   requests whose answers it ignores) fails and closes the connection, so no client holds
//!   a permit by not reading ([`StallGuard`]). Request heads are buffered up to 64 KiB.
//! - **Shutdown**: stop accepting, let requests in flight finish (hyper's graceful shutdown;
//!   SSE streams end on the app's own shutdown signal), for at most `drain` time.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;

/// How the accept loop treats connections (flags of `photonbox serve`).
#[derive(Clone, Debug)]
pub struct ConnLimits {
    /// Connections open at once (further ones wait to be accepted).
    pub max_connections: usize,
    /// Time a client has to send a complete request head, and the longest a kept-alive
    /// connection may sit idle.
    pub header_timeout: Duration,
    /// Longest a response write may make no progress before the connection is closed.
    pub write_timeout: Duration,
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
        .header_read_timeout(limits.header_timeout)
        .max_buf_size(64 << 10);
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
            TokioIo::new(StallGuard::new(stream, limits.write_timeout)),
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

/// A connection whose writes fail once they have made no progress for `timeout`: the
/// peer's receive window stayed full, so it is not reading.
struct StallGuard {
    stream: TcpStream,
    timeout: Duration,
    /// Armed when a write first finds the socket full; cleared by any progress.
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl StallGuard {
    fn new(stream: TcpStream, timeout: Duration) -> StallGuard {
        StallGuard {
            stream,
            timeout,
            stalled: None,
        }
    }

    /// After a write returned `Pending`: an error once the stall has lasted `timeout`.
    fn poll_stall(&mut self, cx: &mut Context<'_>) -> Poll<io::Error> {
        let timeout = self.timeout;
        let sleep = self
            .stalled
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
        match sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(io::Error::new(
                io::ErrorKind::TimedOut,
                "the client stopped reading",
            )),
            Poll::Pending => Poll::Pending,
        }
    }

    fn progress<T>(&mut self, r: Poll<io::Result<T>>, cx: &mut Context<'_>) -> Poll<io::Result<T>> {
        match r {
            Poll::Pending => match self.poll_stall(cx) {
                Poll::Ready(e) => Poll::Ready(Err(e)),
                Poll::Pending => Poll::Pending,
            },
            // Bytes written (or an error): the stall, if any, is over.
            ready => {
                self.stalled = None;
                ready
            }
        }
    }
}

impl AsyncRead for StallGuard {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for StallGuard {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let r = Pin::new(&mut this.stream).poll_write(cx, buf);
        this.progress(r, cx)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let r = Pin::new(&mut this.stream).poll_write_vectored(cx, bufs);
        this.progress(r, cx)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        // A TCP flush is immediate: it says nothing of progress, and must not reset a stall.
        Pin::new(&mut self.get_mut().stream).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_shutdown(cx)
    }
}
