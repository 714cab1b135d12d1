//! Log-log plots of error against time or passes, as SVG (plotters), and the least-squares
//! slope of such a curve.

use std::path::Path;

use anyhow::anyhow;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// One line of a plot: (x, y) points, drawn in order.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// A short label beside each point (the parameter value there), or none.
    pub point_labels: Vec<String>,
}

/// Least-squares fit of ln y = a + b ln x over the points with x, y > 0: (slope b, a).
pub fn loglog_fit(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let b = sxy / sxx;
    Some((b, my - b * mx))
}

/// The chart `loglog_svg` draws on: log10 values on linear axes.
type LogChart<'a, 'b> =
    ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn positive(v: f64) -> bool {
    v > 0.0 && v.is_finite()
}

/// A log-log line plot of `series` to an SVG file.
pub fn loglog_svg(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|&(x, y)| positive(x) && positive(y))
        .collect();
    if all.is_empty() {
        return Err(anyhow!("{}: nothing to plot", path.display()));
    }
    // Plotted as log10 values on linear axes, labelled with the values themselves: ticks
    // then fall evenly inside any range, not only at whole decades.
    let (x0, x1) = log_range(&all, |p| p.0);
    let (y0, y1) = log_range(&all, |p| p.1);
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    let draw = |e: &dyn std::fmt::Display| anyhow!("{}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| draw(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| draw(&e))?;
    chart
        .configure_mesh()
        .x_labels(12)
        .y_labels(12)
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| short(10f64.powf(*v)))
        .y_label_formatter(&|v| short(10f64.powf(*v)))
        .draw()
        .map_err(|e| draw(&e))?;
    for (i, s) in series.iter().enumerate() {
        plot_series(&mut chart, i, s, &draw)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| draw(&e))?;
    root.present().map_err(|e| draw(&e))?;
    Ok(())
}

/// The log10 range of one coordinate of `all`, padded by 6% (at least 0.05) each side.
fn log_range(all: &[(f64, f64)], f: fn(&(f64, f64)) -> f64) -> (f64, f64) {
    let lo = all.iter().map(f).fold(f64::INFINITY, f64::min).log10();
    let hi = all.iter().map(f).fold(f64::NEG_INFINITY, f64::max).log10();
    let pad = ((hi - lo) * 0.06).max(0.05);
    (lo - pad, hi + pad)
}

/// Series `i` of a plot in its palette colour: the line with its legend entry, a dot and
/// the point's label at each point.
fn plot_series(
    chart: &mut LogChart,
    i: usize,
    s: &Series,
    draw: &dyn Fn(&dyn std::fmt::Display) -> anyhow::Error,
) -> anyhow::Result<()> {
    let log = |(x, y): (f64, f64)| (x.log10(), y.log10());
    let color = Palette99::pick(i).to_rgba();
    let pts: Vec<(f64, f64)> = s
        .points
        .iter()
        .copied()
        .filter(|&(x, y)| positive(x) && positive(y))
        .map(log)
        .collect();
    chart
        .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
        .map_err(|e| draw(&e))?
        .label(s.label.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
    chart
        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
        .map_err(|e| draw(&e))?;
    let font = ("sans-serif", 13).into_font().color(&color);
    chart
        .draw_series(
            pts.iter()
                .zip(&s.point_labels)
                .map(|(&p, l)| Text::new(l.clone(), p, font.clone())),
        )
        .map_err(|e| draw(&e))?;
    Ok(())
}

/// A tick label with three significant digits.
fn short(v: f64) -> String {
    if (0.01..10000.0).contains(&v) {
        let digits = (2 - v.log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = (1..=64)
            .map(|i| (i as f64, 3.0 * (i as f64).powf(-0.5)))
            .collect();
        let (b, a) = loglog_fit(&pts).unwrap();
        assert!((b + 0.5).abs() < 1e-9, "{b}");
        assert!((a - 3f64.ln()).abs() < 1e-9);
        assert!(loglog_fit(&[(1.0, 1.0)]).is_none());
    }

    #[test]
    fn plots_an_svg() {
        let dir = std::env::temp_dir().join(format!("pb-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.svg");
        let s = Series {
            label: "k=10".into(),
            points: vec![(0.1, 0.5), (1.0, 0.1), (10.0, 0.02)],
            point_labels: vec!["a".into(), "b".into(), "c".into()],
        };
        loglog_svg(&path, "error", "seconds", "relmse", &[s]).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("k=10") && svg.contains("polyline"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
