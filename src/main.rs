//! The `photonbox` command line: `render` a scene to PNG/EXR, or `serve` jobs over HTTP.

mod progress;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};

use photonbox::render::{self, Control, IntegratorKind, PhotonStore, RenderParams, Scene, output};

#[derive(Parser)]
#[command(name = "photonbox", version, about = "A photon-mapping renderer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a JSON scene to an image.
    Render(RenderArgs),
    /// Serve render jobs over HTTP.
    Serve(ServeArgs),
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
        /// Give the user the admin role (sees and may cancel every job).
        #[arg(long)]
        admin: bool,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum IntegratorArg {
    Raytrace,
    Photon,
    Ppm,
}

#[derive(Clone, Copy, ValueEnum)]
enum StoreArg {
    Indirect,
    All,
    #[value(name = "direct_only")]
    DirectOnly,
}

#[derive(Args)]
struct RenderArgs {
    /// The scene (JSON).
    scene: PathBuf,
    /// Output PNG: 8-bit sRGB of clamp(linear * 2^exposure).
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// Also write linear radiance as 32-bit float OpenEXR.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Write timings, photon counts, effects and radii as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Image width (default: the scene camera's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene camera's).
    #[arg(long)]
    height: Option<u32>,
    #[arg(long, value_enum, default_value = "photon")]
    integrator: IntegratorArg,
    /// Photons emitted for the global map.
    #[arg(long, default_value_t = RenderParams::default().photons)]
    photons: u64,
    /// Photons emitted for the caustic map.
    #[arg(long, default_value_t = RenderParams::default().caustic_photons)]
    caustic_photons: u64,
    /// Photons per radiance estimate.
    #[arg(long, default_value_t = RenderParams::default().k)]
    k: usize,
    /// Which photons the global map keeps.
    #[arg(long, value_enum, default_value = "indirect")]
    photon_store: StoreArg,
    /// Final-gather rays per camera sample (0 reads the global map directly).
    #[arg(long, default_value_t = RenderParams::default().gather_rays)]
    gather_rays: u32,
    /// Jittered samples per pixel.
    #[arg(long, default_value_t = RenderParams::default().spp)]
    spp: u32,
    /// Longest path, in surface interactions.
    #[arg(long, default_value_t = RenderParams::default().max_depth)]
    max_depth: u32,
    #[arg(long, default_value_t = RenderParams::default().seed)]
    seed: u64,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Args)]
struct ServeArgs {
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
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => run_render(args),
        Command::Serve(args) => run_serve(args),
        Command::User(UserCommand::Add { name, data, admin }) => {
            photonbox::server::add_user(&data, &name, admin)
                .map(|token| println!("{token}"))
                .map_err(|e| bad(e.to_string()))
        }
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

fn bad(msg: impl Into<String>) -> anyhow::Error {
    BadInput(msg.into()).into()
}

fn params_from_args(a: &RenderArgs) -> anyhow::Result<RenderParams> {
    let integrator = match a.integrator {
        IntegratorArg::Raytrace => IntegratorKind::Raytrace,
        IntegratorArg::Photon => IntegratorKind::Photon,
        IntegratorArg::Ppm => {
            return Err(bad(
                "--integrator ppm is not available yet: progressive photon mapping is the next \
                 milestone (use raytrace or photon)",
            ));
        }
    };
    let photon_store = match a.photon_store {
        StoreArg::Indirect => PhotonStore::Indirect,
        StoreArg::All => PhotonStore::All,
        StoreArg::DirectOnly => PhotonStore::DirectOnly,
    };
    if !a.exposure.is_finite() {
        return Err(bad("--exposure must be a finite number"));
    }
    let params = RenderParams {
        integrator,
        photons: a.photons,
        caustic_photons: a.caustic_photons,
        k: a.k,
        photon_store,
        gather_rays: a.gather_rays,
        spp: a.spp,
        max_depth: a.max_depth,
        seed: a.seed,
        width: a.width,
        height: a.height,
    };
    params
        .validate()
        .map_err(|e| bad(format!("--{} {}", e.field.replace('_', "-"), e.message)))?;
    Ok(params)
}

fn run_render(a: RenderArgs) -> anyhow::Result<()> {
    let params = params_from_args(&a)?;
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let scene = Scene::load(&a.scene).map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .context("starting the render threads")?;
    let terminal = std::io::stderr().is_terminal();
    let bars = terminal.then(progress::Bars::new);
    let callback = |p: render::Progress| {
        if let Some(b) = &bars {
            b.update(p);
        }
    };
    let control = Control {
        cancel: None,
        progress: Some(&callback),
    };
    let out = pool
        .install(|| render::render(&scene, &params, &control))
        .context("render")?;
    if let Some(b) = &bars {
        b.clear();
    }
    output::write_png(&out.image, a.exposure, &a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(exr) = &a.exr {
        output::write_exr(&out.image, exr).with_context(|| format!("writing {}", exr.display()))?;
    }
    if let Some(path) = &a.stats {
        let json = serde_json::to_string_pretty(&out.stats)?;
        std::fs::write(path, json + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    if terminal {
        let t = &out.stats.times;
        eprintln!(
            "{}x{}: photons {:.2}s, maps {:.2}s, precompute {:.2}s, render {:.2}s, total {:.2}s -> {}",
            out.image.width,
            out.image.height,
            t.photon_trace,
            t.build_maps,
            t.precompute,
            t.render,
            t.total,
            a.output.display()
        );
    }
    Ok(())
}

fn run_serve(a: ServeArgs) -> anyhow::Result<()> {
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let scenes = a.scenes.unwrap_or_else(|| {
        let local = PathBuf::from("scenes");
        if local.is_dir() {
            local
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
        }
    });
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()));
    photonbox::server::serve(photonbox::server::Config {
        addr: a.addr,
        data: a.data,
        scenes,
        threads,
        max_running: a.max_running,
        cache_bytes: a.cache_mb << 20,
        limits: photonbox::server::Limits {
            body_bytes: a.max_body,
            max_pixels: a.max_pixels,
            max_photons: a.max_photons,
            max_k: a.max_k,
            max_iterations: a.max_iterations,
            max_triangles: a.max_triangles,
            max_queued_per_user: a.max_queued,
            memory_bytes: a.memory_mb << 20,
        },
    })
}
