//! The `photonbox` command line: `render` a scene to PNG/EXR, or `serve` jobs over HTTP.

mod cli;
mod progress;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};

#[derive(Parser)]
#[command(name = "photonbox", version, about = "A photon-mapping renderer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a JSON scene to an image.
    Render(cli::render::RenderArgs),
    /// Render every combination of a parameter grid; write errors, times and plots.
    Sweep(cli::sweep::SweepArgs),
    /// Serve render jobs over HTTP.
    Serve(ServeArgs),
    /// Render tasks of a farm's jobs (PostgreSQL store) on this machine.
    Worker(WorkerArgs),
    /// Manage the server's users.
    #[command(subcommand)]
    User(UserCommand),
}

#[derive(Subcommand)]
enum UserCommand {
    /// Add a user and print its token (shown only this once).
    Add {
        name: String,
        #[arg(long, default_value = "./photonbox-data")]
        data: PathBuf,
        /// The farm's store (postgres://...) instead of the data folder's SQLite store.
        #[arg(long)]
        store: Option<String>,
        /// Give the user the admin role (sees and may cancel every job).
        #[arg(long)]
        admin: bool,
    },
}

#[derive(Args)]
struct WorkerArgs {
    /// The farm's store: postgres://user:password@host/database.
    #[arg(long)]
    store: String,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Memory this worker's renders may take (MiB); it claims only tasks that fit.
    #[arg(long, default_value_t = LIMITS.memory_bytes >> 20)]
    memory_mb: u64,
    /// The worker's name in the farm (default: host name and process id).
    #[arg(long)]
    id: Option<String>,
    /// Folder of the built-in scenes (default: ./scenes, else the source tree's).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// Seconds a claimed task stays this worker's without a heartbeat (heartbeats come
    /// three times as often); a worker that stops for longer loses its task to another.
    #[arg(long, default_value_t = 30.0)]
    lease_seconds: f64,
    /// Answer GET /healthz (the store answers, once joined) and /metrics (this worker's
    /// counters) on this address.
    #[arg(long)]
    addr: Option<String>,
}

#[derive(Args)]
struct ServeArgs {
    /// The store: omitted, the embedded SQLite store in --data; postgres://... for a farm
    /// (users, jobs, tasks and results in PostgreSQL; any number of `serve` and `worker`
    /// processes share it).
    #[arg(long)]
    store: Option<String>,
    /// With --store: serve the API only, render nothing on this machine.
    #[arg(long)]
    no_render: bool,
    /// With --store: the lease of the tasks this machine renders (see `worker --help`).
    #[arg(long, default_value_t = 30.0)]
    lease_seconds: f64,
    /// Address to listen on (port 0: any free port; the address is printed).
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Data folder: the SQLite store, result images, the admin token.
    #[arg(long, default_value = "./photonbox-data")]
    data: PathBuf,
    /// Folder of the built-in scenes (default: ./scenes, else the source tree's).
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// Render threads per running job (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Jobs rendering at once, at most one per user.
    #[arg(long, default_value_t = 4)]
    max_running: usize,
    /// Photon-map cache budget (MiB).
    #[arg(long, default_value_t = 1024)]
    cache_mb: u64,
    /// Memory budget of all running renders together (MiB); larger jobs are refused.
    #[arg(long, default_value_t = LIMITS.memory_bytes >> 20)]
    memory_mb: u64,
    /// Largest request body (bytes).
    #[arg(long, default_value_t = LIMITS.body_bytes)]
    max_body: usize,
    /// Largest width*height.
    #[arg(long, default_value_t = LIMITS.max_pixels)]
    max_pixels: u64,
    /// Most photons per map.
    #[arg(long, default_value_t = LIMITS.max_photons)]
    max_photons: u64,
    /// Largest k.
    #[arg(long, default_value_t = LIMITS.max_k)]
    max_k: usize,
    /// Most progressive passes.
    #[arg(long, default_value_t = LIMITS.max_iterations)]
    max_iterations: u32,
    /// Most triangles per scene.
    #[arg(long, default_value_t = LIMITS.max_triangles)]
    max_triangles: usize,
    /// Most queued jobs per user (more: 429).
    #[arg(long, default_value_t = LIMITS.max_queued_per_user)]
    max_queued: usize,
    /// Most work one job may ask for, in ray samples (pixels x spp x (1 + gather rays),
    /// photons, times the passes); larger jobs are refused with the estimate.
    #[arg(long, default_value_t = LIMITS.max_work)]
    max_work: f64,
    /// Disk one user's uploaded scenes and result images may take (MiB); past it, new jobs
    /// are refused until some are deleted.
    #[arg(long, default_value_t = LIMITS.storage_bytes_per_user >> 20)]
    storage_mb: u64,
    /// Connections open at once (kept below the descriptor limit; further ones wait).
    #[arg(long, default_value_t = 4096)]
    max_connections: usize,
    /// Seconds a client has to send a request's headers; also how long an idle kept-alive
    /// connection stays open.
    #[arg(long, default_value_t = 10.0)]
    header_timeout: f64,
    /// Seconds a response write may make no progress (a client that stopped reading)
    /// before the connection is closed.
    #[arg(long, default_value_t = 30.0)]
    write_timeout: f64,
    /// Seconds a client has to send a request body.
    #[arg(long, default_value_t = 60.0)]
    body_timeout: f64,
}

/// The server's default limits, shown by `serve --help`.
const LIMITS: photonbox::server::Limits = photonbox::server::Limits::DEFAULT;

/// Exit codes: 0 success, 1 failure while rendering or writing, 2 bad input.
const EXIT_BAD_INPUT: u8 = 2;

/// An error in what the user gave us (exit code 2), as opposed to a failure (exit code 1).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct BadInput(String);

fn main() -> ExitCode {
    if let Err(missing) = cpu_check() {
        eprintln!(
            "error: this photonbox was built for x86-64-v2 (.cargo/config.toml) and this CPU \
             lacks {missing}; rebuild with RUSTFLAGS=\"-C target-cpu=x86-64\""
        );
        return ExitCode::from(2);
    }
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = parse_cli();
    let result = match cli.command {
        Command::Render(args) => cli::render::run_render(args),
        Command::Sweep(args) => cli::sweep::run_sweep(args),
        Command::Serve(args) => run_serve(args),
        Command::Worker(args) => run_worker(args),
        Command::User(UserCommand::Add {
            name,
            data,
            store,
            admin,
        }) => match store {
            Some(url) => photonbox::farm::run::add_user(&url, &name, admin),
            None => photonbox::server::add_user(&data, &name, admin),
        }
        .map(|token| println!("{token}"))
        .map_err(|e| bad(format!("{e:#}"))),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let bad = e.downcast_ref::<BadInput>().is_some();
            eprintln!("photonbox: error: {e:#}");
            ExitCode::from(if bad { EXIT_BAD_INPUT } else { 1 })
        }
    }
}

/// The command line, with the spec's defaults in the render and sweep help.
fn parse_cli() -> Cli {
    let cmd = Cli::command()
        .mut_subcommand("render", cli::with_spec_defaults)
        .mut_subcommand("sweep", cli::with_spec_defaults);
    Cli::from_arg_matches(&cmd.get_matches()).unwrap_or_else(|e| e.exit())
}

fn bad(msg: impl Into<String>) -> anyhow::Error {
    BadInput(msg.into()).into()
}

/// MiB from a flag, in bytes.
fn mib(n: u64, flag: &str) -> anyhow::Result<u64> {
    n.checked_mul(1 << 20).ok_or_else(|| {
        bad(format!(
            "{flag}: {n} MiB is more than this machine can count"
        ))
    })
}

/// A positive number of seconds from a flag.
fn seconds(s: f64, flag: &str) -> anyhow::Result<std::time::Duration> {
    if !(s.is_finite() && s > 0.0 && s <= 86400.0) {
        return Err(bad(format!(
            "{flag} must be a number of seconds in (0, 86400]"
        )));
    }
    Ok(std::time::Duration::from_secs_f64(s))
}

fn run_serve(a: ServeArgs) -> anyhow::Result<()> {
    if a.max_connections == 0 {
        return Err(bad("--max-connections must be at least 1"));
    }
    if !(a.max_work.is_finite() && a.max_work > 0.0) {
        return Err(bad("--max-work must be a positive number"));
    }
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let scenes = a.scenes.unwrap_or_else(photonbox::server::default_scenes);
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()));
    let limits = photonbox::server::Limits {
        body_bytes: a.max_body,
        max_pixels: a.max_pixels,
        max_photons: a.max_photons,
        max_k: a.max_k,
        max_iterations: a.max_iterations,
        max_triangles: a.max_triangles,
        max_queued_per_user: a.max_queued,
        memory_bytes: mib(a.memory_mb, "--memory-mb")?,
        max_work: a.max_work,
        storage_bytes_per_user: mib(a.storage_mb, "--storage-mb")?,
    };
    let conn = photonbox::server::ConnLimits {
        max_connections: a.max_connections,
        header_timeout: seconds(a.header_timeout, "--header-timeout")?,
        write_timeout: seconds(a.write_timeout, "--write-timeout")?,
        drain: std::time::Duration::from_secs(10),
    };
    let body_timeout = seconds(a.body_timeout, "--body-timeout")?;
    if let Some(store) = a.store {
        if !store.starts_with("postgres://") && !store.starts_with("postgresql://") {
            return Err(bad(format!(
                "--store {store:?}: give a postgres:// URL (omit --store for the embedded SQLite store)"
            )));
        }
        let lease = seconds(a.lease_seconds, "--lease-seconds")?;
        let worker = (!a.no_render).then(|| photonbox::farm::WorkerConfig {
            store: store.clone(),
            id: default_worker_id(),
            threads,
            memory_bytes: limits.memory_bytes,
            scenes,
            lease,
        });
        return photonbox::farm::run::serve(photonbox::farm::run::FarmServeConfig {
            store,
            addr: a.addr,
            limits,
            conn,
            body_timeout,
            worker,
        });
    }
    if a.no_render {
        return Err(bad(
            "--no-render is for a farm: give --store postgres://...",
        ));
    }
    photonbox::server::serve(photonbox::server::Config {
        addr: a.addr,
        data: a.data,
        scenes,
        threads,
        max_running: a.max_running,
        cache_bytes: mib(a.cache_mb, "--cache-mb")?,
        limits,
        conn,
        body_timeout,
    })
}

/// This machine's name and the process id: a worker's default name in the farm.
fn default_worker_id() -> String {
    let host = std::fs::read_to_string("/etc/hostname")
        .ok()
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "worker".into());
    format!("{host}-{}", std::process::id())
}

fn run_worker(a: WorkerArgs) -> anyhow::Result<()> {
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()));
    photonbox::farm::run::work(
        photonbox::farm::WorkerConfig {
            store: a.store,
            id: a.id.unwrap_or_else(default_worker_id),
            threads,
            memory_bytes: mib(a.memory_mb, "--memory-mb")?,
            scenes: a.scenes.unwrap_or_else(photonbox::server::default_scenes),
            lease: seconds(a.lease_seconds, "--lease-seconds")?,
        },
        a.addr,
    )
}

/// The instruction sets this build was compiled for (x86-64-v2 by `.cargo/config.toml`),
/// read from the CPU itself (cpuid leaf 1): `is_x86_feature_detected!` would answer from
/// the build's own target features. Runs before anything else, so an older CPU gets a
/// message instead of an illegal instruction somewhere in the renderer; a build for the
/// baseline (`RUSTFLAGS="-C target-cpu=x86-64"`) asks for none of them.
#[cfg(target_arch = "x86_64")]
fn cpu_check() -> Result<(), &'static str> {
    let compiled_for = [
        (0, "SSE3", cfg!(target_feature = "sse3")),
        (9, "SSSE3", cfg!(target_feature = "ssse3")),
        (13, "CMPXCHG16B", cfg!(target_feature = "cmpxchg16b")),
        (19, "SSE4.1", cfg!(target_feature = "sse4.1")),
        (20, "SSE4.2", cfg!(target_feature = "sse4.2")),
        (23, "POPCNT", cfg!(target_feature = "popcnt")),
    ];
    #[allow(unused_unsafe)]
    // SAFETY: cpuid exists on every x86-64 CPU.
    let ecx = unsafe { std::arch::x86_64::__cpuid(1) }.ecx;
    lacking(ecx, &compiled_for).map_or(Ok(()), Err)
}

/// The first feature (cpuid leaf 1 ecx bit, name, whether the build uses it) that the
/// build uses and whose bit is clear.
#[cfg(target_arch = "x86_64")]
fn lacking(ecx: u32, features: &[(u32, &'static str, bool)]) -> Option<&'static str> {
    features
        .iter()
        .find(|&&(bit, _, used)| used && ecx & (1 << bit) == 0)
        .map(|f| f.1)
}

#[cfg(not(target_arch = "x86_64"))]
fn cpu_check() -> Result<(), &'static str> {
    Ok(())
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_check_names_the_first_missing_feature() {
        let v2 = [(0, "SSE3", true), (9, "SSSE3", true), (20, "SSE4.2", true)];
        let all = (1 << 0) | (1 << 9) | (1 << 20);
        assert_eq!(lacking(all, &v2), None);
        assert_eq!(lacking(all & !(1 << 20), &v2), Some("SSE4.2"));
        assert_eq!(lacking(0, &v2), Some("SSE3"));
        // A baseline build uses none of them, and wants nothing of the CPU.
        assert_eq!(lacking(0, &v2.map(|(b, n, _)| (b, n, false))), None);
        // This machine has what this build uses (x86-64-v2, by .cargo/config.toml).
        assert_eq!(cpu_check(), Ok(()));
    }
}
