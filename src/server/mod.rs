//! The render server: an axum API over a durable job store, a fair render pool and a
//! photon-map cache. See ARCHITECTURE.md for a job's data flow.
//!
//! The server depends on the engine (`crate::render`), never the reverse.

pub(crate) mod api;
pub(crate) mod auth;
pub(crate) mod body;
mod cache;
pub(crate) mod error;
pub(crate) mod events;
mod extract;
mod job_routes;
pub(crate) mod jobs;
pub(crate) mod listen;
mod metrics;
pub(crate) mod needs;
mod openapi;
mod render_job;
mod results;
mod runner;
pub(crate) mod scenes;
mod scheduler;
pub(crate) mod state;
pub(crate) mod store;
pub(crate) mod submit;
pub(crate) mod views;
pub(crate) mod web;

use std::collections::HashMap;
use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use tokio::sync::watch;

pub use listen::ConnLimits;
pub use needs::Limits;

use auth::User;
use cache::MapCache;
use metrics::Metrics;
use scenes::SceneCatalog;
use scheduler::Scheduler;
use state::Jobs;
use store::{JobRow, Status, Store};

/// Everything `photonbox serve` can be told.
#[derive(Clone, Debug)]
pub struct Config {
    pub addr: String,
    pub data: PathBuf,
    /// Built-in scenes (`scenes/`).
    pub scenes: PathBuf,
    /// Render threads per running job.
    pub threads: usize,
    /// Jobs rendering at once (one per user at most).
    pub max_running: usize,
    pub cache_bytes: u64,
    pub limits: Limits,
    /// Connection cap and header/idle timeout of the accept loop.
    pub conn: ConnLimits,
    /// Time a client has to send a request body.
    pub body_timeout: Duration,
}

/// Shared state of a running server.
pub struct App {
    pub config: Config,
    store: Store,
    jobs: Jobs,
    scheduler: Scheduler,
    cache: MapCache,
    catalog: Arc<SceneCatalog>,
    metrics: Metrics,
    /// Users by token hash (tokens never change, so entries never go stale).
    users: Mutex<HashMap<String, User>>,
    user_names: Mutex<HashMap<i64, String>>,
    /// Becomes true when the server shuts down: SSE streams end.
    shutdown: watch::Sender<bool>,
    /// An exclusive lock on the data folder (see [`lock_data_dir`]), held while we run.
    _lock: std::fs::File,
    /// Held from a submission's quota and queue checks to its entry in the job table, so
    /// that parallel submissions of one user cannot all pass the same check. A tokio mutex:
    /// it is held across the store's insert (an await).
    submit: tokio::sync::Mutex<()>,
    /// Request bodies within their size, time and memory bounds.
    bodies: body::BodyReader,
}

pub type AppRef = Arc<App>;

fn ensure_dirs(data: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(data.join("results"))
        .with_context(|| format!("creating {}", data.display()))
}

/// `photonbox user add NAME`: print a new user's token. Before the first `serve` too: the
/// store is created, and with it the admin (its token in `admin-token`), as `serve` would.
pub fn add_user(data: &Path, name: &str, admin: bool) -> anyhow::Result<String> {
    anyhow::ensure!(
        auth::valid_name(name),
        "user name {name:?}: use 1-64 letters, digits, '-', '_' or '.'"
    );
    ensure_dirs(data)?;
    let store = Store::open(data).context("opening the store")?;
    ensure_admin(&store, data)?;
    let (_, token) = store.add_user(name, admin).map_err(|e| match e {
        rusqlite::Error::SqliteFailure(f, _)
            if f.code == rusqlite::ErrorCode::ConstraintViolation =>
        {
            anyhow::anyhow!("a user named {name:?} already exists")
        }
        e => anyhow::anyhow!("adding the user: {e}"),
    })?;
    Ok(token)
}

/// The admin's token, creating the admin (and `admin-token`) in a store without users.
/// An `admin-token` file whose token the store does not know (the store lost its rows, or
/// was replaced) is said loudly and repaired: the admin user is created again with the
/// file's token, so whoever holds the file is not locked out. None if the file is gone.
fn ensure_admin(store: &Store, data: &Path) -> anyhow::Result<Option<String>> {
    let path = data.join("admin-token");
    let file = std::fs::read_to_string(&path)
        .ok()
        .map(|t| t.trim().to_string());
    if store.user_count()? == 0 && file.is_none() {
        let (_, token) = store.add_user("admin", true)?;
        write_admin_token(data, &token)?;
        return Ok(Some(token));
    }
    let Some(token) = file else {
        return Ok(None);
    };
    if !auth::well_formed(&token) {
        tracing::error!(
            "{} does not hold a token (64 hex digits): a new admin token replaces it",
            path.display()
        );
        return new_admin(store, data).map(Some);
    }
    if store
        .user_by_token_hash(&auth::token_hash(&token))?
        .is_some()
    {
        return Ok(Some(token));
    }
    tracing::error!(
        "{} holds a token the store does not know (the store lost rows?): creating the admin \
         user again with it",
        path.display()
    );
    if store.restore_admin(&auth::token_hash(&token)).is_err() {
        // An "admin" with another token exists: the file is stale; a new admin's token
        // replaces it.
        return new_admin(store, data).map(Some);
    }
    Ok(Some(token))
}

/// A further admin user (`admin-` and 8 random hex digits: "admin" is taken, or its token
/// lost) whose token replaces the `admin-token` file.
fn new_admin(store: &Store, data: &Path) -> anyhow::Result<String> {
    let (_, token) = store.add_user(&format!("admin-{}", &auth::new_token()[..8]), true)?;
    write_admin_token(data, &token)?;
    Ok(token)
}

/// Take an exclusive lock on `data/lock` for as long as the returned file is open: a second
/// `serve` on the same folder would otherwise re-queue the first one's running jobs and set
/// its new result files aside as orphans.
fn lock_data_dir(data: &Path) -> anyhow::Result<std::fs::File> {
    use std::os::fd::AsRawFd;
    let path = data.join("lock");
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    // SAFETY: flock on a descriptor we own.
    let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    anyhow::ensure!(
        r == 0,
        "{} is in use by another `photonbox serve` (or it cannot be locked: {})",
        data.display(),
        std::io::Error::last_os_error()
    );
    Ok(file)
}

/// Write the admin token beside the store, readable by its owner only (atomically: a crash
/// never leaves an empty token file).
fn write_admin_token(data: &Path, token: &str) -> anyhow::Result<()> {
    let path = data.join("admin-token");
    crate::render::output::write_atomically(&path, |tmp| {
        let mut opts = std::fs::OpenOptions::new();
        opts.write(true).create(true).truncate(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut opts, 0o600);
        opts.open(tmp)?.write_all(token.as_bytes())
    })
    .with_context(|| format!("writing {}", path.display()))
}

impl App {
    /// Open the data folder (locked for as long as the app lives), recover its jobs, and
    /// return the app with the admin's token (None if its file is gone). Nothing renders
    /// until a dispatcher runs (`serve` starts one), so handler tests can use the app alone.
    pub fn open(config: Config) -> anyhow::Result<(Arc<App>, Option<String>)> {
        ensure_dirs(&config.data)?;
        let lock = lock_data_dir(&config.data)?;
        let store = Store::open(&config.data).context("opening the store")?;
        let admin_token = ensure_admin(&store, &config.data)?;
        let app = Arc::new(App {
            _lock: lock,
            submit: tokio::sync::Mutex::new(()),
            bodies: body::BodyReader::new(config.limits.body_bytes, config.body_timeout),
            scheduler: Scheduler::new(config.max_running, config.limits.memory_bytes),
            cache: MapCache::new(config.cache_bytes),
            catalog: Arc::new(SceneCatalog::load(config.scenes.clone())),
            config,
            store,
            jobs: Jobs::default(),
            metrics: Metrics::default(),
            users: Mutex::new(HashMap::new()),
            user_names: Mutex::new(HashMap::new()),
            shutdown: watch::channel(false).0,
        });
        app.recover()?;
        Ok((app, admin_token))
    }

    /// Load every job; those that were running when the server died run again.
    fn recover(&self) -> anyhow::Result<()> {
        for (id, name) in self.store.user_names()? {
            self.user_names.lock().unwrap().insert(id, name);
        }
        let rows = self.store.all_jobs()?;
        let ids: std::collections::HashSet<i64> = rows.iter().map(|r| r.id).collect();
        results::set_aside_orphans(&self.config.data, &ids);
        for mut row in rows {
            row.result_bytes = results::result_bytes(&self.config.data, row.id);
            if !row.status.is_final() {
                row.result_bytes = row.result_bytes.max(row.result_estimate);
            }
            if row.status == Status::Done && row.result_bytes == 0 {
                tracing::error!(
                    "job {} is done but its result files are gone from {}",
                    row.id,
                    self.config.data.join("results").display()
                );
            }
            if row.status == Status::Running {
                row.status = Status::Queued;
                row.started = None;
                self.store.update_job(&row)?;
            }
            let queued = (row.status == Status::Queued).then_some((row.id, row.user_id));
            let memory = row.memory_bytes;
            self.jobs.insert(row);
            if let Some((id, user)) = queued {
                self.scheduler.enqueue(id, user, memory);
            }
        }
        Ok(())
    }

    /// Change a job's state: written to the store first, then published to pollers and
    /// event streams, so nothing is seen that a crash could take back. None if the job is
    /// gone.
    fn commit_job(&self, id: i64, f: impl FnOnce(&mut JobRow)) -> Option<JobRow> {
        let mut row = self.jobs.row(id)?;
        f(&mut row);
        if let Err(e) = self.store.update_job(&row) {
            tracing::error!("job {id}: store: {e}");
        }
        if row.status.is_final() {
            // A progressive job's saved state is kept only while the job may resume.
            results::remove_results(&self.config.data, id, &["ppmstate"]);
            row.result_bytes = results::result_bytes(&self.config.data, id);
        }
        self.jobs.publish(row.clone()).then_some(row)
    }

    /// A user's name, from memory only (handlers never wait on the store for it): every
    /// user is loaded at start, and one added since (`photonbox user add`) is learnt when it
    /// first authenticates, which it must have done to own a job.
    fn user_name(&self, id: i64) -> String {
        self.user_names
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&id)
            .cloned()
            .unwrap_or_else(|| format!("user{id}"))
    }
}

/// The whole HTTP API and gallery as one router over `app`: `serve` runs it on its accept
/// loop; tests can call it with `tower::ServiceExt::oneshot`, without a socket.
pub fn app(app: AppRef) -> axum::Router {
    api::router(app)
}

/// The built-in scenes' folder: ./scenes if there is one, else the source tree's.
pub fn default_scenes() -> PathBuf {
    let local = PathBuf::from("scenes");
    if local.is_dir() {
        local
    } else {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
    }
}

/// Run the server until SIGINT or SIGTERM. Prints the address and a sign-in URL.
pub fn serve(config: Config) -> anyhow::Result<()> {
    let (app, admin_token) = App::open(config.clone())?;
    let dispatcher = {
        let app = app.clone();
        std::thread::Builder::new()
            .name("dispatcher".into())
            .spawn(move || Scheduler::run_dispatcher(app))?
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(&config.addr)
            .await
            .with_context(|| format!("listening on {}", config.addr))?;
        let addr: SocketAddr = listener.local_addr()?;
        println!("photonbox: listening on http://{addr}");
        match &admin_token {
            Some(t) => println!("photonbox: gallery (signed in as admin): http://{addr}/?token={t}"),
            None => println!(
                "photonbox: gallery: http://{addr}/ (the admin token file is gone; add a user with `photonbox user add NAME`)"
            ),
        }
        let _ = std::io::stdout().flush();
        let router = self::app(app.clone());
        let app2 = app.clone();
        let mut conn = config.conn.clone();
        conn.max_connections = listen::connection_cap(conn.max_connections);
        tracing::info!("at most {} connections at once", conn.max_connections);
        listen::serve(listener, router, conn, async move {
            shutdown_signal().await;
            tracing::info!("shutting down");
            // End SSE streams and stop renders (they go back to the queue).
            app2.shutdown.send_replace(true);
            app2.scheduler.stop();
        })
        .await;
        anyhow::Ok(())
    })?;
    app.scheduler.stop();
    if !app.scheduler.wait_idle(Duration::from_secs(10)) {
        tracing::warn!("renders still running at exit; they run again at the next start");
    }
    let _ = dispatcher.join();
    println!("photonbox: stopped");
    Ok(())
}

pub(crate) async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {},
        _ = term => {},
    }
}
