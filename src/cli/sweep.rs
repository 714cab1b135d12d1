//! `photonbox sweep`: render every combination of a parameter grid against a reference and
//! write what each costs and how accurate it is: DIR/results.csv, DIR/passes.csv (ppm, per
//! pass) and log-log plots of error against time (one series per value of the other
//! parameters) and of the ppm error per pass with its fitted slope.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use serde_json::Value;

use super::render::{read_reference, spec_from_flags};
use super::sweep_output::{Row, describe_choice, write_plots, write_results};
use crate::bad;
use photonbox::render::{self, Control, Image, Inputs, RenderError, Scene, output};
use photonbox::spec::{REFERENCE_INTEGRATOR, SpecForm};

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
    /// Parameters every render shares (the grid overrides them; a render whose integrator
    /// does not read one, e.g. `--iterations` for `photon`, goes without it).
    #[command(flatten)]
    spec: SpecForm,
}

/// One grid axis: a parameter and its values, as written.
pub struct Axis {
    pub name: String,
    pub values: Vec<String>,
}

/// Grid names that are not a field of the spec's form.
const ALIASES: &[(&str, &[&str])] = &[("n", &["photons", "caustic_photons"])];

/// Fields of the form the grid does not vary: they are not render parameters, or not one
/// value.
const NOT_AXES: &[&str] = &["version", "effects", "exposure", "reference_job"];

fn parse_grid(grid: &[String]) -> anyhow::Result<Vec<Axis>> {
    let fields = form_fields();
    let mut axes: Vec<Axis> = Vec::new();
    for g in grid {
        let (name, values) = g
            .split_once('=')
            .ok_or_else(|| bad(format!("--grid {g}: expected NAME=V1,V2,...")))?;
        let name = name.trim().replace('-', "_");
        let known = fields.contains(&name) || ALIASES.iter().any(|(a, _)| *a == name);
        if !known || NOT_AXES.contains(&name.as_str()) {
            let mut names: Vec<&str> = ALIASES.iter().map(|(a, _)| *a).collect();
            names.extend(fields.iter().map(String::as_str));
            names.retain(|n| !NOT_AXES.contains(n));
            return Err(bad(format!(
                "--grid {g}: unknown parameter {name:?} (one of {})",
                names.join(", ")
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

/// The names of the form's fields, as its schema lists them.
fn form_fields() -> Vec<String> {
    use utoipa::openapi::{RefOr, schema::Schema};
    match <SpecForm as utoipa::PartialSchema>::schema() {
        RefOr::T(Schema::Object(o)) => o.properties.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

/// `base` with one parameter set from its text (a number where it reads as one, else a
/// name), through the form's own deserializer: its names, types and errors.
fn set(base: &SpecForm, name: &str, v: &str) -> anyhow::Result<SpecForm> {
    let value: Value = serde_json::from_str(v).unwrap_or_else(|_| Value::String(v.into()));
    let mut form = serde_json::to_value(base)?;
    let fields = ALIASES
        .iter()
        .find(|(a, _)| *a == name)
        .map_or(vec![name], |(_, f)| f.to_vec());
    for f in fields {
        form[f] = value.clone();
    }
    let mut out: SpecForm =
        serde_json::from_value(form).map_err(|e| bad(format!("--grid {name}={v}: {e}")))?;
    // The CLI's switches are not in the serialized form.
    (out.blind_caustics, out.no_direct_light) = (base.blind_caustics, base.no_direct_light);
    (out.no_caustics, out.no_diffuse_interreflection) =
        (base.no_caustics, base.no_diffuse_interreflection);
    Ok(out)
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
    let axes = parse_grid(&a.grid)?;
    let combos = combinations(&axes);
    // Check every combination before rendering any.
    let mut specs = Vec::new();
    for c in &combos {
        let mut form = a.spec.clone();
        for (axis, &i) in axes.iter().zip(c) {
            form = set(&form, &axis.name, &axis.values[i])?;
        }
        specs.push(spec_from_flags(
            &form.only_fields_of_its_integrator(),
            true,
        )?);
    }
    let scene = Scene::load(&a.scene).map_err(|e| bad(format!("{}: {e}", a.scene.display())))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let reference = match &a.reference {
        Some(p) => read_reference(p)?,
        None => render_reference(&a, &scene)?,
    };
    let mut rows = Vec::new();
    for (c, spec) in combos.iter().zip(&specs) {
        let label = describe_choice(&axes, c);
        eprintln!("sweep: {label}");
        reset_peak_rss();
        let inputs = Inputs {
            reference: Some(&reference),
            ..Inputs::fresh()
        };
        let out = render::run(&scene, spec, inputs, &Control::none(), &mut |_| {
            ControlFlow::Continue(())
        })
        .map_err(|e| match e {
            RenderError::Input(_) | RenderError::Spec(_) => bad(format!("{label}: {e}")),
            e => anyhow::Error::new(e).context("render"),
        })?;
        let error = out.stats.error.unwrap_or_default();
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
    let base = &a.spec;
    let form = SpecForm {
        integrator: Some(REFERENCE_INTEGRATOR),
        iterations: Some(a.reference_passes),
        // Another seed than the renders it measures: a ppm render compared with a
        // reference made from the same random numbers would show no error at all.
        seed: Some(base.seed.unwrap_or(1).wrapping_add(REFERENCE_SEED_OFFSET)),
        // All its passes, however long they take.
        time_limit: None,
        target_error: None,
        ..base.clone()
    };
    let spec = spec_from_flags(&form, false)?;
    let path = a.out.join("reference.exr");
    let (photons, caustic) = spec
        .photon_mapping()
        .map_or((0, 0), |p| (p.photons, p.caustic_photons));
    eprintln!(
        "sweep: no --reference given: rendering one with {}, {} passes of {photons} + \
         {caustic} photons, seed {}, into {}",
        REFERENCE_INTEGRATOR.as_str(),
        a.reference_passes,
        spec.seed,
        path.display()
    );
    let t = Instant::now();
    let out = render::render(scene, &spec, &Control::none()).context("reference")?;
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
