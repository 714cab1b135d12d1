//! `photonbox render`: one scene to PNG/EXR/STATS.json, with `photon`, `raytrace` or
//! progressive `ppm` (checkpointed and resumable), and errors against a reference.

use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Args, ValueEnum};

use crate::{bad, progress};
use photonbox::render::accuracy::ImageError;
use photonbox::render::ppm::{self, PpmOptions, PpmState, StateError, Stop};
use photonbox::render::{
    self, Control, EffectSwitches, Image, IntegratorKind, PhotonStore, RenderOutput, RenderParams,
    Scene, output,
};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum IntegratorArg {
    Raytrace,
    Photon,
    Ppm,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum StoreArg {
    Indirect,
    All,
    #[value(name = "direct_only")]
    DirectOnly,
}

/// What shapes the image: shared by `render` and `sweep`.
#[derive(Args, Clone, Debug)]
pub struct ParamArgs {
    /// Image width (default: the scene camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene camera's).
    #[arg(long)]
    pub height: Option<u32>,
    #[arg(long, value_enum, default_value = "photon")]
    pub integrator: IntegratorArg,
    /// Photons emitted for the global map [default: 200000; ppm: 100000 per pass].
    #[arg(long)]
    pub photons: Option<u64>,
    /// Photons emitted for the caustic map [default: 200000; ppm: 100000 per pass].
    #[arg(long)]
    pub caustic_photons: Option<u64>,
    /// Photons per radiance estimate; ppm: sets the automatic initial radius [default: 50;
    /// ppm: 10].
    #[arg(long)]
    pub k: Option<usize>,
    /// Which photons the global map keeps.
    #[arg(long, value_enum, default_value = "indirect")]
    pub photon_store: StoreArg,
    /// Final-gather rays per camera sample, 0 reads the global map [default: 8; ppm: 0].
    #[arg(long)]
    pub gather_rays: Option<u32>,
    /// Jittered samples per pixel (ppm: per pass) [default: 4; ppm: 1].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Longest path, in surface interactions.
    #[arg(long, default_value_t = RenderParams::default().max_depth)]
    pub max_depth: u32,
    #[arg(long, default_value_t = RenderParams::default().seed)]
    pub seed: u64,
    /// ppm: passes [default: 16].
    #[arg(long)]
    pub iterations: Option<u32>,
    /// ppm: radius reduction per pass, in (0, 1).
    #[arg(long, default_value_t = RenderParams::default().alpha)]
    pub alpha: f64,
    /// ppm: initial radius in scene units [default: median k-NN distance in pass 1].
    #[arg(long)]
    pub radius: Option<f32>,
    /// Emit caustic photons in every direction (as the seed did) instead of aiming them at
    /// the mirror and glass objects.
    #[arg(long)]
    pub blind_caustics: bool,
    /// Leave out direct light at what the camera sees (to see the other effects alone).
    #[arg(long)]
    pub no_direct_light: bool,
    /// Leave out caustics: no caustic photons are traced.
    #[arg(long)]
    pub no_caustics: bool,
    /// Leave out light from other diffuse surfaces (no global-map reads, no gathering).
    #[arg(long, alias = "no-indirect")]
    pub no_diffuse_interreflection: bool,
}

#[derive(Args)]
pub struct RenderArgs {
    /// The scene (JSON).
    scene: PathBuf,
    /// Output PNG: 8-bit sRGB of clamp(linear * 2^exposure).
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// Also write linear radiance as 32-bit float OpenEXR.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Write timings, photon counts, effects, radii and errors as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    #[command(flatten)]
    params: ParamArgs,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Linear EXR reference: print and record relmse, block_err, mean_ratio (ppm: per pass).
    #[arg(long)]
    reference: Option<PathBuf>,
    /// ppm: stop before a pass that would end after this many seconds (passes only).
    #[arg(long)]
    time_limit: Option<f64>,
    /// ppm: stop once relmse against --reference is at most this.
    #[arg(long, requires = "reference")]
    target_error: Option<f64>,
    /// ppm: save the running state here after every pass (and the image to -o/--exr).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// ppm: continue from a state saved by --checkpoint (same scene and parameters).
    #[arg(long)]
    resume: Option<PathBuf>,
}

/// Render parameters from the flags, with the integrator's defaults, validated.
pub fn params_from_args(a: &ParamArgs) -> anyhow::Result<RenderParams> {
    let integrator = match a.integrator {
        IntegratorArg::Raytrace => IntegratorKind::Raytrace,
        IntegratorArg::Photon => IntegratorKind::Photon,
        IntegratorArg::Ppm => IntegratorKind::Ppm,
    };
    let d = if integrator == IntegratorKind::Ppm {
        RenderParams::ppm_defaults()
    } else {
        RenderParams::default()
    };
    let photon_store = match a.photon_store {
        StoreArg::Indirect => PhotonStore::Indirect,
        StoreArg::All => PhotonStore::All,
        StoreArg::DirectOnly => PhotonStore::DirectOnly,
    };
    let params = RenderParams {
        integrator,
        photons: a.photons.unwrap_or(d.photons),
        caustic_photons: a.caustic_photons.unwrap_or(d.caustic_photons),
        k: a.k.unwrap_or(d.k),
        photon_store,
        gather_rays: a.gather_rays.unwrap_or(d.gather_rays),
        spp: a.spp.unwrap_or(d.spp),
        max_depth: a.max_depth,
        seed: a.seed,
        width: a.width,
        height: a.height,
        iterations: a.iterations.unwrap_or(d.iterations),
        alpha: a.alpha,
        radius: a.radius,
        aim_caustics: !a.blind_caustics,
        effects: EffectSwitches {
            direct_light: !a.no_direct_light,
            caustics: !a.no_caustics,
            diffuse_interreflection: !a.no_diffuse_interreflection,
        },
    };
    params
        .validate()
        .map_err(|e| bad(format!("--{} {}", e.field.replace('_', "-"), e.message)))?;
    Ok(params)
}

/// Flags that only `ppm` reads: an error elsewhere, rather than silently ignored.
fn check_ppm_only(a: &RenderArgs, ppm: bool) -> anyhow::Result<()> {
    for (flag, set) in [
        ("--time-limit", a.time_limit.is_some()),
        ("--target-error", a.target_error.is_some()),
        ("--checkpoint", a.checkpoint.is_some()),
        ("--resume", a.resume.is_some()),
    ] {
        if set && !ppm {
            return Err(bad(format!("{flag} is only for --integrator ppm")));
        }
    }
    if let Some(t) = a.time_limit
        && !(t > 0.0 && t.is_finite())
    {
        return Err(bad(format!(
            "--time-limit must be a positive number of seconds, got {t}"
        )));
    }
    if let Some(e) = a.target_error
        && !(e > 0.0 && e.is_finite())
    {
        return Err(bad(format!(
            "--target-error must be a positive number, got {e}"
        )));
    }
    Ok(())
}

pub fn read_reference(path: &Path) -> anyhow::Result<Image> {
    output::read_exr(path).map_err(|e| bad(format!("--reference {}: {e}", path.display())))
}

pub fn run_render(a: RenderArgs) -> anyhow::Result<()> {
    let params = params_from_args(&a.params)?;
    let is_ppm = params.integrator == IntegratorKind::Ppm;
    check_ppm_only(&a, is_ppm)?;
    if !a.exposure.is_finite() {
        return Err(bad("--exposure must be a finite number"));
    }
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let (scene, source) = Scene::load_with_source(&a.scene)
        .map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    let reference = a.reference.as_deref().map(read_reference).transpose()?;
    let resume = match &a.resume {
        Some(p) => {
            let f = std::fs::File::open(p)
                .map_err(|e| bad(format!("--resume {}: {e}", p.display())))?;
            match PpmState::load(std::io::BufReader::new(f)) {
                Ok(state) => Some(state),
                // A damaged state cannot be resumed, but the render it was for can still
                // be made: from the start, and saying so.
                Err(e @ StateError::Corrupt { .. }) => {
                    eprintln!(
                        "photonbox: warning: --resume {}: {e}; starting again from pass 0",
                        p.display()
                    );
                    None
                }
                Err(e) => return Err(bad(format!("--resume {}: {e}", p.display()))),
            }
        }
        None => None,
    };
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
    let out = if is_ppm {
        let stop = Stop {
            time_limit: a.time_limit,
            target_error: a.target_error,
            ..Stop::after(params.iterations)
        };
        let opts = PpmOptions {
            reference: reference.as_ref(),
            resume,
            ..PpmOptions::new(stop, ppm::fingerprint(source.as_bytes(), &params))
        };
        let mut on_pass = |state: &PpmState| {
            if let Err(e) = checkpoint(&a, state) {
                eprintln!("photonbox: warning: checkpoint: {e:#}");
            }
            if let (false, Some(h)) = (terminal, &state.last)
                && let Some(e) = h.error
            {
                eprintln!("pass {}: {:.2}s {}", h.pass, h.elapsed, describe(&e));
            }
            ControlFlow::Continue(())
        };
        let r = pool.install(|| ppm::render_ppm(&scene, &params, opts, &control, &mut on_pass));
        match r {
            Ok(o) => o.output,
            Err(ppm::PpmError::Input(msg)) => return Err(bad(msg)),
            Err(e) => return Err(anyhow::Error::new(e).context("render")),
        }
    } else {
        let mut out = pool
            .install(|| render::render(&scene, &params, &control))
            .context("render")?;
        out.measure(reference.as_ref())
            .map_err(|e| bad(format!("--reference: {e}")))?;
        out
    };
    if let Some(b) = &bars {
        b.clear();
    }
    write_outputs(&a, &out)?;
    if let Some(e) = &out.stats.error {
        println!("{}", describe(e));
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

/// One line of errors against the reference.
pub fn describe(e: &ImageError) -> String {
    format!(
        "relmse {:.6} block_err {:.5} mean_ratio {:.5}",
        e.relmse, e.block_err, e.mean_ratio
    )
}

fn write_outputs(a: &RenderArgs, out: &RenderOutput) -> anyhow::Result<()> {
    write_images(a, &out.image)?;
    if let Some(path) = &a.stats {
        let json = serde_json::to_string_pretty(&out.stats)? + "\n";
        output::write_atomically(path, |t| std::fs::write(t, &json))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn write_images(a: &RenderArgs, image: &Image) -> anyhow::Result<()> {
    output::write_images(image, a.exposure, &a.output, a.exr.as_deref())
        .with_context(|| format!("writing {}", a.output.display()))
}

/// After a ppm pass: the preview images and the state, each replaced atomically, so that
/// a crash leaves the last complete pass on disk.
fn checkpoint(a: &RenderArgs, state: &PpmState) -> anyhow::Result<()> {
    let Some(path) = &a.checkpoint else {
        return Ok(());
    };
    write_images(a, &state.image())?;
    state
        .save_file(path)
        .with_context(|| format!("writing {}", path.display()))
}
