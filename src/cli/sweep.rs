//! `photonbox sweep`: render every combination of a parameter grid against a reference and
//! write what each costs and how accurate it is: DIR/results.csv, DIR/passes.csv (ppm, per
//! pass) and log-log plots of error against time (one series per value of the other
//! parameters) and of the ppm error per pass with its fitted slope.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use super::render::{IntegratorArg, ParamArgs, StoreArg, params_from_args, read_reference};
use super::sweep_output::{Row, describe_choice, write_plots, write_results};
use crate::bad;
use photonbox::render::accuracy::compare;
use photonbox::render::ppm::{self, PpmOptions, Stop};
use photonbox::render::{self, Control, Image, IntegratorKind, Scene, output};

#[derive(Args)]
pub struct SweepArgs {
    /// The scene (JSON).
    scene: PathBuf,
    /// Output folder (created).
    #[arg(short = 'o', long = "output")]
    out: PathBuf,
    /// Linear EXR reference (default: render a long ppm reference first, into DIR).
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Passes of the ppm reference rendered when no --reference is given.
    #[arg(long, default_value_t = 256)]
    reference_passes: u32,
    /// Parameters to vary, each NAME=V1,V2,... (names as the flags, with _ or -; `n` sets
    /// photons and caustic_photons together).
    #[arg(long, num_args = 1.., required = true)]
    grid: Vec<String>,
    /// ppm: stop each render's passes at this many seconds.
    #[arg(long)]
    time_limit: Option<f64>,
    /// Parameters every render shares (the grid overrides them).
    #[command(flatten)]
    params: ParamArgs,
}

/// One grid axis: a parameter and its values, as written.
pub struct Axis {
    pub name: String,
    pub values: Vec<String>,
}

const AXES: &[&str] = &[
    "n",
    "integrator",
    "photons",
    "caustic_photons",
    "k",
    "photon_store",
    "gather_rays",
    "spp",
    "max_depth",
    "iterations",
    "alpha",
    "radius",
];

fn parse_grid(grid: &[String]) -> anyhow::Result<Vec<Axis>> {
    let mut axes: Vec<Axis> = Vec::new();
    for g in grid {
        let (name, values) = g
            .split_once('=')
            .ok_or_else(|| bad(format!("--grid {g}: expected NAME=V1,V2,...")))?;
        let name = name.trim().replace('-', "_");
        if !AXES.contains(&name.as_str()) {
            return Err(bad(format!(
                "--grid {g}: unknown parameter {name:?} (one of {})",
                AXES.join(", ")
            )));
        }
        if axes.iter().any(|a| a.name == name) {
            return Err(bad(format!("--grid: {name} given twice")));
        }
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        if values.iter().any(|v| v.is_empty()) {
            return Err(bad(format!("--grid {g}: empty value")));
        }
        axes.push(Axis { name, values });
    }
    Ok(axes)
}

/// `base` with one parameter set from its text.
fn set(base: &mut ParamArgs, name: &str, v: &str) -> anyhow::Result<()> {
    fn num<T: std::str::FromStr>(name: &str, v: &str) -> anyhow::Result<T> {
        v.parse()
            .map_err(|_| bad(format!("--grid {name}={v}: not a valid number")))
    }
    match name {
        "integrator" => {
            base.integrator = match v {
                "raytrace" => IntegratorArg::Raytrace,
                "photon" => IntegratorArg::Photon,
                "ppm" => IntegratorArg::Ppm,
                _ => {
                    return Err(bad(format!(
                        "--grid integrator={v}: expected raytrace, photon or ppm"
                    )));
                }
            }
        }
        "photon_store" => {
            base.photon_store = match v {
                "indirect" => StoreArg::Indirect,
                "all" => StoreArg::All,
                "direct_only" => StoreArg::DirectOnly,
                _ => {
                    return Err(bad(format!(
                        "--grid photon_store={v}: expected indirect, all or direct_only"
                    )));
                }
            }
        }
        "n" => {
            let n = num(name, v)?;
            (base.photons, base.caustic_photons) = (Some(n), Some(n));
        }
        "photons" => base.photons = Some(num(name, v)?),
        "caustic_photons" => base.caustic_photons = Some(num(name, v)?),
        "k" => base.k = Some(num(name, v)?),
        "gather_rays" => base.gather_rays = Some(num(name, v)?),
        "spp" => base.spp = Some(num(name, v)?),
        "max_depth" => base.max_depth = num(name, v)?,
        "iterations" => base.iterations = Some(num(name, v)?),
        "alpha" => base.alpha = num(name, v)?,
        "radius" => base.radius = Some(num(name, v)?),
        _ => unreachable!("checked by parse_grid"),
    }
    Ok(())
}

/// Every combination, first axis slowest: the values chosen, by axis.
fn combinations(axes: &[Axis]) -> Vec<Vec<usize>> {
    let mut out = vec![vec![]];
    for a in axes {
        out = out
            .into_iter()
            .flat_map(|c| {
                (0..a.values.len()).map(move |i| {
                    let mut c = c.clone();
                    c.push(i);
                    c
                })
            })
            .collect();
    }
    out
}

pub fn run_sweep(a: SweepArgs) -> anyhow::Result<()> {
    if let Some(t) = a.time_limit
        && !(t > 0.0 && t.is_finite())
    {
        return Err(bad(format!(
            "--time-limit must be a positive number of seconds, got {t}"
        )));
    }
    let axes = parse_grid(&a.grid)?;
    let combos = combinations(&axes);
    // Check every combination before rendering any.
    let mut all_params = Vec::new();
    for c in &combos {
        let mut pa = a.params.clone();
        for (axis, &i) in axes.iter().zip(c) {
            set(&mut pa, &axis.name, &axis.values[i])?;
        }
        if !matches!(pa.integrator, IntegratorArg::Ppm) {
            // ppm's settings apply to the ppm renders of a grid that mixes integrators.
            let d = photonbox::render::RenderParams::default();
            (pa.iterations, pa.alpha, pa.radius) = (None, d.alpha, None);
        }
        all_params.push(params_from_args(&pa)?);
    }
    let scene = Scene::load(&a.scene).map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let reference = match &a.reference {
        Some(p) => read_reference(p)?,
        None => render_reference(&a, &scene)?,
    };
    let mut rows = Vec::new();
    for (c, params) in combos.iter().zip(&all_params) {
        let label = describe_choice(&axes, c);
        eprintln!("sweep: {label}");
        reset_peak_rss();
        let mut out = if params.integrator == IntegratorKind::Ppm {
            // Through render_ppm, for the error after every pass.
            let stop = Stop {
                time_limit: a.time_limit,
                ..Stop::after(params.iterations)
            };
            let opts = PpmOptions {
                reference: Some(&reference),
                ..PpmOptions::new(stop, String::new())
            };
            ppm::render_ppm(&scene, params, opts, &Control::none(), &mut |_| {
                ControlFlow::Continue(())
            })
            .map_err(|e| bad(format!("{label}: {e}")))?
            .output
        } else {
            render::render(&scene, params, &Control::none()).context("render")?
        };
        let error = match out.stats.error {
            Some(e) => e,
            None => {
                compare(&out.image, &reference).map_err(|e| bad(format!("--reference: {e}")))?
            }
        };
        out.stats.error = Some(error);
        eprintln!(
            "  {:.2}s  {}",
            out.stats.times.total,
            super::render::describe(&error)
        );
        rows.push(Row {
            choice: c.clone(),
            out,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    write_results(&a.out, &axes, &rows)?;
    write_plots(&a.out, &axes, &rows)?;
    eprintln!("sweep: {} renders -> {}", rows.len(), a.out.display());
    Ok(())
}

/// Added to the seed of a reference the sweep renders itself.
const REFERENCE_SEED_OFFSET: u64 = 1_000_003;

/// Without --reference: a long ppm render at the sweep's resolution, saved beside the results.
fn render_reference(a: &SweepArgs, scene: &Scene) -> anyhow::Result<Image> {
    let mut pa = a.params.clone();
    pa.integrator = IntegratorArg::Ppm;
    pa.iterations = Some(a.reference_passes);
    // Another seed than the renders it measures: a ppm render compared with a reference
    // made from the same random numbers would show no error at all.
    pa.seed = pa.seed.wrapping_add(REFERENCE_SEED_OFFSET);
    let params = params_from_args(&pa)?;
    let path = a.out.join("reference.exr");
    eprintln!(
        "sweep: no --reference given: rendering one with ppm, {} passes of {} + {} photons, seed {}, into {}",
        params.iterations,
        params.photons,
        params.caustic_photons,
        params.seed,
        path.display()
    );
    let t = Instant::now();
    let out = render::render(scene, &params, &Control::none()).context("reference")?;
    output::write_exr(&out.image, &path).with_context(|| format!("writing {}", path.display()))?;
    eprintln!("sweep: reference done in {:.1}s", t.elapsed().as_secs_f64());
    Ok(out.image)
}

/// Linux: reset the process's peak resident set (VmHWM) so that it measures the next render.
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The peak resident set since the last reset, in MiB (Linux only).
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
