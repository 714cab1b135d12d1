//! `photonbox render`: one scene to PNG/EXR/STATS.json as the spec's flags say (a
//! progressive render checkpointed and resumable), with errors against a reference.

use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use crate::{bad, progress};
use photonbox::render::accuracy::ImageError;
use photonbox::render::ppm::{PpmState, StateError};
use photonbox::render::{
    self, Control, Image, Inputs, RenderError, RenderOutput, Scene, TraceNow, output,
};
use photonbox::spec::{RenderSpec, SpecForm, progressive_names};

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
    spec: SpecForm,
    /// PNG exposure in stops.
    #[arg(long, default_value_t = 0.0)]
    exposure: f32,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Linear EXR reference: print and record relmse, block_err, mean_ratio (ppm: per pass).
    #[arg(long)]
    reference: Option<PathBuf>,
    /// A progressive render: save the running state here after every pass (and the image
    /// to -o/--exr).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// A progressive render: continue from a state saved by --checkpoint (same scene and
    /// parameters).
    #[arg(long)]
    resume: Option<PathBuf>,
}

/// The spec the flags describe, with the integrator's defaults, validated (an error names
/// its flag). `has_reference`: a reference comes with the render.
pub fn spec_from_flags(form: &SpecForm, has_reference: bool) -> anyhow::Result<RenderSpec> {
    form.to_spec(has_reference).map_err(|e| bad(e.as_flag()))
}

/// Checkpoints are for progressive renders only: an error elsewhere, rather than ignored.
fn check_progressive_only(a: &RenderArgs, spec: &RenderSpec) -> anyhow::Result<()> {
    for (flag, set) in [
        ("--checkpoint", a.checkpoint.is_some()),
        ("--resume", a.resume.is_some()),
    ] {
        if set && !spec.is_progressive() {
            return Err(bad(format!(
                "{flag} is only for a progressive integrator ({})",
                progressive_names()
            )));
        }
    }
    Ok(())
}

pub fn read_reference(path: &Path) -> anyhow::Result<Image> {
    output::read_exr(path).map_err(|e| bad(format!("--reference {}: {e}", path.display())))
}

pub fn run_render(a: RenderArgs) -> anyhow::Result<()> {
    // The exposure is checked with the spec's other numbers.
    let form = SpecForm {
        exposure: Some(a.exposure),
        ..a.spec.clone()
    };
    let spec = spec_from_flags(&form, a.reference.is_some())?;
    check_progressive_only(&a, &spec)?;
    if a.threads == Some(0) {
        return Err(bad("--threads must be at least 1"));
    }
    let (scene, source) = Scene::load_with_source(&a.scene)
        .map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    let reference = a.reference.as_deref().map(read_reference).transpose()?;
    let resume = read_resume(a.resume.as_deref())?;
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
    let inputs = Inputs {
        maps: &TraceNow,
        reference: reference.as_ref(),
        resume,
        scene_key: source.as_bytes(),
        piece: None,
        rows: None,
        choice: None,
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
    let out = match pool.install(|| render::run(&scene, &spec, inputs, &control, &mut on_pass)) {
        Ok(out) => out,
        Err(e @ (RenderError::Input(_) | RenderError::Spec(_))) => return Err(bad(e.to_string())),
        Err(e) => return Err(anyhow::Error::new(e).context("render")),
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
            "{}x{}: choice {:.2}s, photons {:.2}s, maps {:.2}s, precompute {:.2}s, render {:.2}s, \
             total {:.2}s -> {}",
            out.image.width,
            out.image.height,
            t.choose,
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

/// The state `--resume` names. A damaged state cannot be resumed, but the render it was for
/// can still be made: from the start, and saying so.
fn read_resume(path: Option<&Path>) -> anyhow::Result<Option<PpmState>> {
    let Some(p) = path else { return Ok(None) };
    let f = std::fs::File::open(p).map_err(|e| bad(format!("--resume {}: {e}", p.display())))?;
    match PpmState::load(std::io::BufReader::new(f)) {
        Ok(state) => Ok(Some(state)),
        Err(e @ StateError::Corrupt { .. }) => {
            eprintln!(
                "photonbox: warning: --resume {}: {e}; starting again from pass 0",
                p.display()
            );
            Ok(None)
        }
        Err(e) => Err(bad(format!("--resume {}: {e}", p.display()))),
    }
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
