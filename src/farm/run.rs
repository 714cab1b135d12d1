//! The farm's processes: `serve --store postgres://...` (an API instance, and a worker
//! beside it unless `--no-render`) and `worker --store ...`, each until SIGINT or SIGTERM;
//! and `user add --store ...`.

use std::io::Write;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::sync::watch;

use super::Queue;
use super::api::{FarmApi, router};
use super::worker::{WorkerConfig, run_worker};
use crate::server::auth::{new_token, token_hash};
use crate::server::body::BodyReader;
use crate::server::needs::Limits;
use crate::server::scenes::SceneCatalog;
use crate::server::{ConnLimits, shutdown_signal};

/// Everything `photonbox serve --store postgres://...` can be told.
#[derive(Clone, Debug)]
pub struct FarmServeConfig {
    pub store: String,
    pub addr: String,
    pub limits: Limits,
    pub conn: ConnLimits,
    pub body_timeout: Duration,
    /// The worker that renders beside the API (None: `--no-render`).
    pub worker: Option<WorkerConfig>,
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?)
}

/// A watch that turns true at SIGINT or SIGTERM.
fn on_signal() -> watch::Receiver<bool> {
    let (tx, rx) = watch::channel(false);
    tokio::spawn(async move {
        shutdown_signal().await;
        tx.send_replace(true);
    });
    rx
}

/// Run an API instance (and its worker) until SIGINT or SIGTERM.
pub fn serve(cfg: FarmServeConfig) -> anyhow::Result<()> {
    runtime()?.block_on(async {
        let queue = Queue::connect(&cfg.store, 16)
            .await
            .context("connecting to the store")?;
        let admin_token = first_admin(&queue).await?;
        if let Some(token) = &admin_token {
            println!("photonbox: admin token (shown once): {token}");
        }
        let scenes = cfg
            .worker
            .as_ref()
            .map(|w| w.scenes.clone())
            .unwrap_or_else(crate::server::default_scenes);
        let catalog = tokio::task::spawn_blocking(move || SceneCatalog::load(scenes)).await?;
        let api = Arc::new(FarmApi {
            queue,
            catalog: Arc::new(catalog),
            limits: cfg.limits.clone(),
            bodies: BodyReader::new(cfg.limits.body_bytes, cfg.body_timeout),
            previews: Default::default(),
        });
        let listener = tokio::net::TcpListener::bind(&cfg.addr)
            .await
            .with_context(|| format!("listening on {}", cfg.addr))?;
        let addr: SocketAddr = listener.local_addr()?;
        println!("photonbox: listening on http://{addr} (farm store)");
        match &admin_token {
            Some(t) => {
                println!("photonbox: gallery (signed in as admin): http://{addr}/?token={t}")
            }
            None => println!("photonbox: gallery: http://{addr}/"),
        }
        let _ = std::io::stdout().flush();
        let stop = on_signal();
        let worker = cfg
            .worker
            .clone()
            .map(|w| tokio::spawn(run_worker(w, stop.clone(), watch::channel(None).0)));
        let mut stop2 = stop.clone();
        crate::server::listen::serve(listener, router(api), cfg.conn.clone(), async move {
            let _ = stop2.wait_for(|s| *s).await;
        })
        .await;
        if let Some(w) = worker {
            w.await??;
        }
        println!("photonbox: stopped");
        anyhow::Ok(())
    })
}

/// Run a worker until SIGINT or SIGTERM (its task given back); with `addr`, it also
/// answers `/healthz` and `/metrics` there.
pub fn work(cfg: WorkerConfig, addr: Option<String>) -> anyhow::Result<()> {
    runtime()?.block_on(async {
        let stop = on_signal();
        let (joined, joined_rx) = watch::channel(None);
        let probes = match addr {
            Some(addr) => {
                let listener = tokio::net::TcpListener::bind(&addr)
                    .await
                    .with_context(|| format!("listening on {addr}"))?;
                println!(
                    "photonbox: worker probes on http://{}",
                    listener.local_addr()?
                );
                let mut stop = stop.clone();
                let app = super::probe::worker_router(joined_rx);
                Some(tokio::spawn(async move {
                    axum::serve(listener, app)
                        .with_graceful_shutdown(async move {
                            let _ = stop.wait_for(|s| *s).await;
                        })
                        .await
                }))
            }
            None => None,
        };
        println!("photonbox: worker {} on the farm store", cfg.id);
        let _ = std::io::stdout().flush();
        let worked = run_worker(cfg, stop, joined).await;
        if let Some(p) = probes {
            p.await??;
        }
        worked
    })
}

/// Add a user to the farm's store; returns its token.
pub fn add_user(store: &str, name: &str, admin: bool) -> anyhow::Result<String> {
    anyhow::ensure!(
        crate::server::auth::valid_name(name),
        "user name {name:?}: use 1-64 letters, digits, '-', '_' or '.'"
    );
    runtime()?.block_on(async {
        let queue = Queue::connect(store, 1)
            .await
            .context("connecting to the store")?;
        let token = new_token();
        queue
            .add_user(name, &token_hash(&token), admin)
            .await
            .map_err(|e| anyhow::anyhow!("adding the user {name:?} (does it exist?): {e}"))?;
        Ok(token)
    })
}

/// The admin of a store without users, created; its token.
async fn first_admin(queue: &Queue) -> anyhow::Result<Option<String>> {
    let users: i64 = sqlx::query_scalar("SELECT count(*) FROM users")
        .fetch_one(queue.pool())
        .await?;
    if users > 0 {
        return Ok(None);
    }
    let token = new_token();
    // Two instances starting on an empty store: one admin, the other insert refused.
    match queue.add_user("admin", &token_hash(&token), true).await {
        Ok(_) => Ok(Some(token)),
        Err(_) => Ok(None),
    }
}
