//! `photonbox sweep`: render every combination of a parameter grid against a reference and
//! write what each costs and how accurate it is: DIR/results.csv, DIR/passes.csv (ppm, per
//! pass) and log-log plots of error against time (one series per value of the other
//! parameters) and of the ppm error per pass with its fitted slope.

use std::fmt::Write as _;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use super::plot::{Series, loglog_fit, loglog_svg};
use super::render::{IntegratorArg, ParamArgs, StoreArg, params_from_args, read_reference};
use crate::bad;
use photonbox::render::accuracy::{ImageError, compare};
use photonbox::render::ppm::{self, PassStats, PpmOptions, Stop};
use photonbox::render::{self, Control, Image, IntegratorKind, RenderOutput, Scene, output};

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
struct Axis {
    name: String,
    values: Vec<String>,
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
        "k" => base.k = num(name, v)?,
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

/// One rendered combination.
struct Row {
    choice: Vec<usize>,
    out: RenderOutput,
    error: ImageError,
    passes: Vec<PassStats>,
    peak_rss_mb: Option<f64>,
}

pub fn run_sweep(a: SweepArgs) -> anyhow::Result<()> {
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
    let source = std::fs::read(&a.scene)
        .map_err(|e| bad(format!("{}: cannot read: {e}", a.scene.display())))?;
    let scene = Scene::load(&a.scene).map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let reference = match &a.reference {
        Some(p) => read_reference(p)?,
        None => render_reference(&a, &scene, &source)?,
    };
    let mut rows = Vec::new();
    for (c, params) in combos.iter().zip(&all_params) {
        let label = describe_choice(&axes, c);
        eprintln!("sweep: {label}");
        reset_peak_rss();
        let (out, passes) = if params.integrator == IntegratorKind::Ppm {
            let opts = PpmOptions {
                stop: Stop {
                    iterations: params.iterations,
                    time_limit: a.time_limit,
                    target_error: None,
                },
                reference: Some(&reference),
                resume: None,
                fingerprint: ppm::fingerprint(&source, params),
            };
            let o = ppm::render_ppm(&scene, params, opts, &Control::none(), &mut |_| {
                ControlFlow::Continue(())
            })
            .map_err(|e| bad(format!("{label}: {e}")))?;
            let passes = o.state.history.clone();
            (o.output, passes)
        } else {
            let out = render::render(&scene, params, &Control::none()).context("render")?;
            (out, Vec::new())
        };
        let error =
            compare(&out.image, &reference).map_err(|e| bad(format!("--reference: {e}")))?;
        eprintln!(
            "  {:.2}s  {}",
            out.stats.times.total,
            super::render::describe(&error)
        );
        rows.push(Row {
            choice: c.clone(),
            out,
            error,
            passes,
            peak_rss_mb: peak_rss_mb(),
        });
    }
    write_results(&a, &axes, &rows)?;
    write_plots(&a.out, &axes, &rows)?;
    eprintln!("sweep: {} renders -> {}", rows.len(), a.out.display());
    Ok(())
}

/// Added to the seed of a reference the sweep renders itself.
const REFERENCE_SEED_OFFSET: u64 = 1_000_003;

/// Without --reference: a long ppm render at the sweep's resolution, saved beside the results.
fn render_reference(a: &SweepArgs, scene: &Scene, source: &[u8]) -> anyhow::Result<Image> {
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
    let opts = PpmOptions {
        stop: Stop {
            iterations: params.iterations,
            time_limit: None,
            target_error: None,
        },
        reference: None,
        resume: None,
        fingerprint: ppm::fingerprint(source, &params),
    };
    let o = ppm::render_ppm(scene, &params, opts, &Control::none(), &mut |_| {
        ControlFlow::Continue(())
    })
    .map_err(|e| bad(format!("reference: {e}")))?;
    output::write_exr(&o.output.image, &path)
        .with_context(|| format!("writing {}", path.display()))?;
    eprintln!("sweep: reference done in {:.1}s", t.elapsed().as_secs_f64());
    Ok(o.output.image)
}

fn describe_choice(axes: &[Axis], c: &[usize]) -> String {
    axes.iter()
        .zip(c)
        .map(|(a, &i)| format!("{}={}", a.name, a.values[i]))
        .collect::<Vec<_>>()
        .join(" ")
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

/// The CSV columns of results.csv, after the grid's parameters.
pub const RESULT_COLUMNS: &[&str] = &[
    "integrator",
    "photons",
    "caustic_photons",
    "k",
    "gather_rays",
    "spp",
    "passes",
    "photon_trace_s",
    "build_maps_s",
    "precompute_s",
    "render_s",
    "total_s",
    "relmse",
    "block_err",
    "mean_ratio",
    "global_stored",
    "caustic_stored",
    "peak_rss_mb",
];

fn write_results(a: &SweepArgs, axes: &[Axis], rows: &[Row]) -> anyhow::Result<()> {
    let mut csv = String::new();
    let header: Vec<String> = axes
        .iter()
        .map(|x| format!("grid_{}", x.name))
        .chain(RESULT_COLUMNS.iter().map(|s| s.to_string()))
        .collect();
    writeln!(csv, "{}", header.join(","))?;
    let mut passes = String::from(
        "combination,pass,elapsed_s,radius_global,radius_caustic,relmse,block_err,mean_ratio\n",
    );
    for (n, r) in rows.iter().enumerate() {
        let s = &r.out.stats;
        let p = &s.params;
        let t = &s.times;
        let mut fields: Vec<String> = axes
            .iter()
            .zip(&r.choice)
            .map(|(x, &i)| x.values[i].clone())
            .collect();
        fields.extend([
            p.integrator.clone(),
            p.photons.to_string(),
            p.caustic_photons.to_string(),
            p.k.to_string(),
            p.gather_rays.to_string(),
            p.spp.to_string(),
            s.ppm.as_ref().map_or(1, |x| x.passes).to_string(),
            format!("{:.6}", t.photon_trace),
            format!("{:.6}", t.build_maps),
            format!("{:.6}", t.precompute),
            format!("{:.6}", t.render),
            format!("{:.6}", t.total),
            format!("{:.8}", r.error.relmse),
            format!("{:.8}", r.error.block_err),
            format!("{:.8}", r.error.mean_ratio),
            s.photons.global_stored.to_string(),
            s.photons.caustic_stored.to_string(),
            r.peak_rss_mb.map_or(String::new(), |m| format!("{m:.1}")),
        ]);
        writeln!(csv, "{}", fields.join(","))?;
        for h in &r.passes {
            if let Some(e) = h.error {
                writeln!(
                    passes,
                    "{n},{},{:.6},{:.6},{:.6},{:.8},{:.8},{:.8}",
                    h.pass,
                    h.elapsed,
                    h.radius_global,
                    h.radius_caustic,
                    e.relmse,
                    e.block_err,
                    e.mean_ratio
                )?;
            }
        }
    }
    let path = a.out.join("results.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    if rows.iter().any(|r| !r.passes.is_empty()) {
        let path = a.out.join("passes.csv");
        std::fs::write(&path, passes).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn write_plots(dir: &Path, axes: &[Axis], rows: &[Row]) -> anyhow::Result<()> {
    // Error against time: for each axis with several values, one series per choice of the
    // other axes, along which this axis varies.
    for (ai, axis) in axes.iter().enumerate() {
        if axis.values.len() < 2 {
            continue;
        }
        for metric in ["relmse", "block_err"] {
            let mut groups: Vec<(Vec<usize>, Series)> = Vec::new();
            for r in rows {
                let mut others = r.choice.clone();
                others.remove(ai);
                let y = if metric == "relmse" {
                    r.error.relmse
                } else {
                    r.error.block_err
                };
                let point = (r.out.stats.times.total, y);
                match groups.iter_mut().find(|(o, _)| *o == others) {
                    Some((_, s)) => s.points.push(point),
                    None => {
                        let mut label: Vec<String> = axes
                            .iter()
                            .enumerate()
                            .filter(|(j, _)| *j != ai)
                            .map(|(j, x)| format!("{}={}", x.name, x.values[r.choice[j]]))
                            .collect();
                        if label.is_empty() {
                            label.push("all".into());
                        }
                        let label = format!(
                            "{} ({} {}..{})",
                            label.join(" "),
                            axis.name,
                            axis.values[0],
                            axis.values.last().unwrap()
                        );
                        groups.push((
                            others,
                            Series {
                                label,
                                points: vec![point],
                            },
                        ));
                    }
                }
            }
            let series: Vec<Series> = groups.into_iter().map(|(_, s)| s).collect();
            let path = dir.join(format!("{metric}_vs_time_by_{}.svg", axis.name));
            let title = format!("{metric} against render time, varying {}", axis.name);
            loglog_svg(&path, &title, "seconds", metric, &series)?;
        }
    }
    // ppm: error per pass, with the fitted log-log slope.
    let ppm_series: Vec<Series> = rows
        .iter()
        .filter(|r| r.passes.len() >= 2)
        .map(|r| {
            let points: Vec<(f64, f64)> = r
                .passes
                .iter()
                .filter_map(|h| h.error.map(|e| (h.pass as f64, e.relmse)))
                .collect();
            let slope =
                loglog_fit(&points).map_or(String::new(), |(b, _)| format!(" slope {b:.2}"));
            Series {
                label: format!("{}{slope}", describe_choice(axes, &r.choice)),
                points,
            }
        })
        .collect();
    if !ppm_series.is_empty() {
        let path = dir.join("ppm_relmse_per_pass.svg");
        loglog_svg(
            &path,
            "ppm: relmse against passes (fitted slope)",
            "pass",
            "relmse",
            &ppm_series,
        )?;
    }
    Ok(())
}
