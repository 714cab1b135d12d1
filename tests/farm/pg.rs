//! A real PostgreSQL for the farm's tests and benchmark: Debian's server (.ci/run
//! installs it when missing), a cluster made by initdb in a temporary directory, listening
//! on a free loopback port, one database per test. Run as root (CI), the server runs as the
//! `postgres` user, which PostgreSQL requires.
//!
//! The server is a child of a thread that lives as long as it does, with PR_SET_PDEATHSIG,
//! so it dies with the test process however that ends; a normal exit stops it cleanly and
//! removes the directory (atexit).

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, OnceLock, mpsc};
use std::time::{Duration, Instant};

pub struct Cluster {
    pub port: u16,
    dir: PathBuf,
    bin: PathBuf,
    owner: Option<(u32, u32)>,
    /// fsync on (the benchmark: commits cost what they cost in production) or off (tests:
    /// a restart of the server, a fast shutdown, loses nothing either way).
    durable: bool,
    /// The running server's pid and a receiver told when it has exited.
    server: Mutex<Option<(i32, mpsc::Receiver<()>)>>,
}

static CLUSTER: OnceLock<Cluster> = OnceLock::new();
/// Every cluster's running server and directory, for the clean-up at exit.
static PIDS: Mutex<Vec<i32>> = Mutex::new(Vec::new());
static DIRS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The test process's shared cluster, made and started on first use.
pub fn cluster() -> &'static Cluster {
    CLUSTER.get_or_init(|| Cluster::new(false))
}

extern "C" fn stop_at_exit() {
    let pids = std::mem::take(&mut *PIDS.lock().unwrap_or_else(|e| e.into_inner()));
    for &pid in &pids {
        // SIGINT: PostgreSQL's fast shutdown.
        unsafe { libc::kill(pid, libc::SIGINT) };
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    for pid in pids {
        while unsafe { libc::kill(pid, 0) } == 0 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    for dir in DIRS.lock().unwrap_or_else(|e| e.into_inner()).iter() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// Where Debian's PostgreSQL keeps its programs (the newest version installed), or
/// $PHOTONBOX_PG_BIN.
fn bin_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("PHOTONBOX_PG_BIN") {
        return d.into();
    }
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .expect("PostgreSQL is not installed (.ci/run installs Debian's `postgresql`)")
        .filter_map(|e| {
            let e = e.ok()?;
            let v = e.file_name().to_str()?.parse().ok()?;
            Some((v, e.path().join("bin")))
        })
        .filter(|(_, p)| p.join("postgres").exists())
        .collect();
    versions.sort();
    versions
        .pop()
        .expect("no /usr/lib/postgresql/*/bin/postgres")
        .1
}

/// The `postgres` user's uid and gid when we are root (PostgreSQL refuses to run as root).
fn owner() -> Option<(u32, u32)> {
    if unsafe { libc::geteuid() } != 0 {
        return None;
    }
    let pw = unsafe { libc::getpwnam(c"postgres".as_ptr()) };
    assert!(
        !pw.is_null(),
        "running as root, and there is no `postgres` user"
    );
    Some(unsafe { ((*pw).pw_uid, (*pw).pw_gid) })
}

fn chown(path: &Path, owner: Option<(u32, u32)>) {
    if let Some((u, g)) = owner {
        std::os::unix::fs::chown(path, Some(u), Some(g)).unwrap();
    }
}

fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

impl Cluster {
    /// A cluster of its own (for a test that stops or restarts the server, or the
    /// benchmark), started; `durable`: fsync on.
    pub fn new(durable: bool) -> Cluster {
        static AT_EXIT: std::sync::Once = std::sync::Once::new();
        // SAFETY: registering a plain extern "C" function that takes no arguments.
        AT_EXIT.call_once(|| unsafe {
            libc::atexit(stop_at_exit);
        });
        let c = Cluster::init(durable);
        c.start();
        c
    }

    fn init(durable: bool) -> Cluster {
        let dir = tempfile::Builder::new()
            .prefix("photonbox-pg-")
            .tempdir()
            .unwrap()
            .keep();
        DIRS.lock().unwrap().push(dir.clone());
        let owner = owner();
        chown(&dir, owner);
        let bin = bin_dir();
        let mut initdb = Command::new(bin.join("initdb"));
        initdb
            .args(["--auth=trust", "--username=photonbox", "--encoding=UTF8"])
            .args(["--no-sync", "--no-instructions", "-D"])
            .arg(dir.join("data"))
            .stdout(Stdio::null());
        if let Some((u, g)) = owner {
            initdb.uid(u).gid(g);
        }
        let status = initdb.status().expect("run initdb");
        assert!(status.success(), "initdb failed: {status}");
        Cluster {
            port: free_port(),
            dir,
            bin,
            owner,
            durable,
            server: Mutex::new(None),
        }
    }

    /// Start the server and wait until it accepts connections.
    pub fn start(&self) {
        let mut server = self.server.lock().unwrap();
        assert!(server.is_none(), "the server is running");
        let log = self.dir.join(format!("server-{}.log", next_log()));
        let log_file = std::fs::File::create(&log).unwrap();
        chown(&log, self.owner);
        let mut cmd = Command::new(self.bin.join("postgres"));
        cmd.arg("-D")
            .arg(self.dir.join("data"))
            .args(["-p", &self.port.to_string(), "-k"])
            .arg(&self.dir)
            .args([
                "-c",
                "listen_addresses=127.0.0.1",
                "-c",
                "max_connections=300",
            ])
            .args([
                "-c",
                if self.durable {
                    "fsync=on"
                } else {
                    "fsync=off"
                },
            ])
            .args(["-c", "shared_buffers=64MB"])
            .stdout(Stdio::null())
            .stderr(log_file);
        if let Some((u, g)) = self.owner {
            cmd.uid(u).gid(g);
        }
        // SAFETY: prctl is async-signal-safe.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                Ok(())
            });
        }
        let (pid_tx, pid_rx) = mpsc::channel();
        let (exit_tx, exit_rx) = mpsc::channel();
        // The parent thread must outlive the server (PDEATHSIG follows the thread).
        std::thread::spawn(move || {
            let mut child = cmd.spawn().expect("start postgres");
            pid_tx.send(child.id() as i32).unwrap();
            let _ = child.wait();
            let _ = exit_tx.send(());
        });
        let pid = pid_rx.recv().unwrap();
        PIDS.lock().unwrap().push(pid);
        *server = Some((pid, exit_rx));
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let text = std::fs::read_to_string(&log).unwrap_or_default();
            if text.contains("ready to accept connections") {
                return;
            }
            let exited = server.as_ref().unwrap().1.try_recv().is_ok();
            assert!(
                !exited && Instant::now() < deadline,
                "postgres did not start:\n{text}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Stop the server (fast shutdown: sessions are ended, committed work is kept).
    pub fn stop(&self) {
        let Some((pid, exited)) = self.server.lock().unwrap().take() else {
            return;
        };
        unsafe { libc::kill(pid, libc::SIGINT) };
        exited
            .recv_timeout(Duration::from_secs(30))
            .expect("postgres stops");
        PIDS.lock().unwrap().retain(|&p| p != pid);
    }

    /// The URL of database `db`.
    pub fn url(&self, db: &str) -> String {
        format!("postgres://photonbox@127.0.0.1:{}/{db}", self.port)
    }

    /// A new, empty database of its own for one test; returns its URL.
    pub async fn fresh_db(&self) -> String {
        static N: AtomicU32 = AtomicU32::new(0);
        let name = format!(
            "t{}_{}",
            std::process::id(),
            N.fetch_add(1, Ordering::SeqCst)
        );
        let mut admin = <sqlx::PgConnection as sqlx::Connection>::connect(&self.url("postgres"))
            .await
            .unwrap();
        // The name is ours (digits and an underscore), so formatting it in is safe.
        let create = sqlx::AssertSqlSafe(format!("CREATE DATABASE {name}"));
        sqlx::raw_sql(create).execute(&mut admin).await.unwrap();
        self.url(&name)
    }
}

fn next_log() -> u32 {
    static N: AtomicU32 = AtomicU32::new(0);
    N.fetch_add(1, Ordering::SeqCst)
}

/// A user row, as the API will write it (the farm's tests and benchmark seed the store
/// directly).
pub async fn insert_user(pool: &sqlx::PgPool, id: i64, name: &str) {
    sqlx::query(
        "INSERT INTO users (id, name, token_hash, admin, created) VALUES ($1, $2, $2, false, 0)",
    )
    .bind(id)
    .bind(name)
    .execute(pool)
    .await
    .unwrap();
}

/// A queued job row of `user`, created at `created`, needing `memory` bytes (no tasks yet).
pub async fn insert_job(pool: &sqlx::PgPool, id: i64, user: i64, created: f64, memory: u64) {
    sqlx::query(
        "INSERT INTO jobs (id, user_id, public, status, params_json, memory_bytes, created)
         VALUES ($1, $2, false, 'queued', '{}', $3, $4)",
    )
    .bind(id)
    .bind(user)
    .bind(memory as i64)
    .bind(created)
    .execute(pool)
    .await
    .unwrap();
}
