//! What `sweep` writes: results.csv, passes.csv and the log-log plots.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;

use super::plot::{Series, loglog_fit, loglog_svg};
use super::sweep::Axis;
use photonbox::render::RenderOutput;
use photonbox::render::accuracy::ImageError;
use photonbox::render::ppm::PassStats;

/// The per-pass error slope is fitted from this pass on (when there are 8 or more).
const FIT_FROM_PASS: u32 = 4;

/// One rendered combination; `out.stats.error` is its error against the reference.
pub struct Row {
    pub choice: Vec<usize>,
    pub out: RenderOutput,
    pub peak_rss_mb: Option<f64>,
}

impl Row {
    fn error(&self) -> ImageError {
        self.out.stats.error.unwrap_or_default()
    }

    /// The ppm passes (none for other integrators).
    fn passes(&self) -> &[PassStats] {
        self.out.stats.ppm.as_ref().map_or(&[], |p| &p.history)
    }

    /// results.csv's columns after the grid's, as (name, value).
    fn fields(&self) -> Vec<(&'static str, String)> {
        let s = &self.out.stats;
        let (p, t, e) = (&s.params, &s.times, self.error());
        vec![
            (
                "integrator",
                p.integrator
                    .map_or(String::new(), |i| i.as_str().to_string()),
            ),
            ("photons", shown(p.photons)),
            ("caustic_photons", shown(p.caustic_photons)),
            ("k", shown(p.k)),
            ("gather_rays", shown(p.gather_rays)),
            ("spp", shown(p.spp)),
            ("passes", s.ppm.as_ref().map_or(1, |x| x.passes).to_string()),
            ("photon_trace_s", format!("{:.6}", t.photon_trace)),
            ("build_maps_s", format!("{:.6}", t.build_maps)),
            ("precompute_s", format!("{:.6}", t.precompute)),
            ("render_s", format!("{:.6}", t.render)),
            ("total_s", format!("{:.6}", t.total)),
            ("relmse", format!("{:.8}", e.relmse)),
            ("block_err", format!("{:.8}", e.block_err)),
            ("mean_ratio", format!("{:.8}", e.mean_ratio)),
            ("global_stored", s.photons.global_stored.to_string()),
            ("caustic_stored", s.photons.caustic_stored.to_string()),
            (
                "peak_rss_mb",
                self.peak_rss_mb
                    .map_or(String::new(), |m| format!("{m:.1}")),
            ),
        ]
    }
}

/// A field its integrator reads, or nothing.
fn shown<T: ToString>(v: Option<T>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

pub fn describe_choice(axes: &[Axis], c: &[usize]) -> String {
    axes.iter()
        .zip(c)
        .map(|(a, &i)| format!("{}={}", a.name, a.values[i]))
        .collect::<Vec<_>>()
        .join(" ")
}

pub fn write_results(dir: &Path, axes: &[Axis], rows: &[Row]) -> anyhow::Result<()> {
    let mut csv = String::new();
    if let Some(first) = rows.first() {
        let header: Vec<String> = axes
            .iter()
            .map(|x| format!("grid_{}", x.name))
            .chain(first.fields().into_iter().map(|(name, _)| name.to_string()))
            .collect();
        writeln!(csv, "{}", header.join(","))?;
    }
    let mut passes = String::from(
        "combination,pass,elapsed_s,radius_global,radius_caustic,relmse,block_err,mean_ratio\n",
    );
    for (n, r) in rows.iter().enumerate() {
        let mut fields: Vec<String> = axes
            .iter()
            .zip(&r.choice)
            .map(|(x, &i)| x.values[i].clone())
            .collect();
        fields.extend(r.fields().into_iter().map(|(_, v)| v));
        writeln!(csv, "{}", fields.join(","))?;
        for h in r.passes() {
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
    let path = dir.join("results.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    if rows.iter().any(|r| !r.passes().is_empty()) {
        let path = dir.join("passes.csv");
        std::fs::write(&path, passes).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

pub fn write_plots(dir: &Path, axes: &[Axis], rows: &[Row]) -> anyhow::Result<()> {
    // Error against time: for each axis with several values, one series per choice of the
    // other axes, along which this axis varies.
    for (ai, axis) in axes.iter().enumerate() {
        if axis.values.len() < 2 {
            continue;
        }
        for metric in ["relmse", "block_err"] {
            let series = series_against_time(axes, ai, metric, rows);
            let path = dir.join(format!("{metric}_vs_time_by_{}.svg", axis.name));
            let title = format!("{metric} against render time, varying {}", axis.name);
            loglog_svg(&path, &title, "seconds", metric, &series)?;
        }
    }
    // ppm: error per pass, with the fitted log-log slope.
    let ppm_series: Vec<Series> = rows
        .iter()
        .filter(|r| r.passes().len() >= 2)
        .map(|r| ppm_pass_series(axes, r))
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

/// `metric` against total time as axis `ai` varies: one series per choice of the other
/// axes, in the order of their first row, each point labelled with axis `ai`'s value.
fn series_against_time(axes: &[Axis], ai: usize, metric: &str, rows: &[Row]) -> Vec<Series> {
    let axis = &axes[ai];
    let mut groups: Vec<(Vec<usize>, Series)> = Vec::new();
    for r in rows {
        let mut others = r.choice.clone();
        others.remove(ai);
        let y = if metric == "relmse" {
            r.error().relmse
        } else {
            r.error().block_err
        };
        let point = (r.out.stats.times.total, y);
        let value = axis.values[r.choice[ai]].clone();
        match groups.iter_mut().find(|(o, _)| *o == others) {
            Some((_, s)) => {
                s.points.push(point);
                s.point_labels.push(value);
            }
            None => {
                let label = series_label(axes, ai, &r.choice);
                groups.push((
                    others,
                    Series {
                        label,
                        points: vec![point],
                        point_labels: vec![value],
                    },
                ));
            }
        }
    }
    groups.into_iter().map(|(_, s)| s).collect()
}

/// The legend of a series along axis `ai`: the other axes' values in `choice` ("all" if
/// there are none), then the range axis `ai` runs over.
fn series_label(axes: &[Axis], ai: usize, choice: &[usize]) -> String {
    let axis = &axes[ai];
    let mut label: Vec<String> = axes
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != ai)
        .map(|(j, x)| format!("{}={}", x.name, x.values[choice[j]]))
        .collect();
    if label.is_empty() {
        label.push("all".into());
    }
    format!(
        "{} ({} {}..{})",
        label.join(" "),
        axis.name,
        axis.values[0],
        axis.values.last().unwrap()
    )
}

/// One ppm row's relmse against pass, labelled with its combination and fitted slope.
fn ppm_pass_series(axes: &[Axis], r: &Row) -> Series {
    let points: Vec<(f64, f64)> = r
        .passes()
        .iter()
        .filter_map(|h| h.error.map(|e| (h.pass as f64, e.relmse)))
        .collect();
    // The slope past the first passes' transient, as docs/accuracy.md reports it.
    let from = if points.len() >= 8 { FIT_FROM_PASS } else { 1 };
    let tail: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0 >= from as f64)
        .collect();
    let slope = loglog_fit(&tail).map_or(String::new(), |(b, _)| {
        format!(" slope {b:.2} (passes >= {from})")
    });
    Series {
        label: format!("{}{slope}", describe_choice(axes, &r.choice)),
        points,
        point_labels: Vec::new(),
    }
}
