//! Plot helpers shared by every figure: the bundled font (pure Rust text rendering).

use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static INIT: Once = Once::new();

/// Registers the bundled DejaVu Sans as plotters' "sans-serif" family (idempotent).
pub fn register_fonts() {
    INIT.call_once(|| {
        for style in [
            plotters::style::FontStyle::Normal,
            plotters::style::FontStyle::Bold,
            plotters::style::FontStyle::Italic,
            plotters::style::FontStyle::Oblique,
        ] {
            // The font is bundled and valid; registration only fails on malformed bytes.
            let _ = plotters::style::register_font("sans-serif", style, FONT);
        }
    });
}

use std::path::Path;

use anyhow::{anyhow, Result};
use edgekf::scenario::{PlotSpec, Scenario};
use edgekf::sim::Results;
use plotters::prelude::*;

const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(0, 0, 0),
];

fn colour(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

/// Axis label (with units) of a metric.
pub fn metric_label(metric: &str) -> &'static str {
    match metric {
        "est_error" => "estimation error ε_k = ‖x_k − x̂_k|k‖ [m]",
        "est_error_sq" => "squared estimation error ε_k² [m²]",
        "cov_trace" => "trace of posterior covariance [m²]",
        "procrustes" => "Procrustes error [m]",
        _ => "value",
    }
}

fn draw_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// Renders one figure request into `path` (a PNG; the caller stages it under a temporary name).
/// Estimators without data for the figure (e.g. diverged before its first point) are left out.
pub fn render(path: &Path, spec: &PlotSpec, sc: &Scenario, res: &Results) -> Result<()> {
    register_fonts();
    let labels: Vec<String> = spec
        .estimators()
        .map(<[String]>::to_vec)
        .unwrap_or_else(|| res.labels().iter().map(|s| s.to_string()).collect());
    match spec {
        PlotSpec::Metric { metric, log_y, .. } => {
            metric_plot(path, spec, metric, *log_y, res, &labels)
        }
        PlotSpec::Inputs { agent, .. } => inputs_plot(path, spec, *agent, sc, res, &labels),
        PlotSpec::Paths { .. } => paths_plot(path, spec, sc, res, &labels),
    }
}

fn metric_plot(
    path: &Path,
    spec: &PlotSpec,
    metric: &str,
    log_y: bool,
    res: &Results,
    labels: &[String],
) -> Result<()> {
    let t: Vec<f64> = res.steps.iter().map(|&k| k as f64 * res.dt).collect();
    let tmax = *t.last().unwrap_or(&1.0);
    let mut series = Vec::new();
    for l in labels {
        if let Some(s) = res.series(l, metric) {
            series.push((l.clone(), s));
        }
    }
    // y range over the bands (positive part on a log axis).
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (_, s) in &series {
        for (m, sd) in s.mean.iter().zip(&s.std) {
            let sd = if sd.is_finite() { *sd } else { 0.0 };
            let (a, b) = (m - sd, m + sd);
            hi = hi.max(b);
            if log_y {
                if *m > 0.0 {
                    lo = lo.min(if a > 0.0 { a } else { *m });
                }
            } else {
                lo = lo.min(a);
            }
        }
    }
    if !lo.is_finite() || !hi.is_finite() {
        lo = 1e-6;
        hi = 1.0;
    }
    let root = BitMapBackend::new(path, (1100, 720)).into_drawing_area();
    root.fill(&WHITE).map_err(draw_err)?;
    let title = if spec.title().is_empty() {
        metric.to_string()
    } else {
        spec.title().to_string()
    };
    let n = res.runs.len();
    let caption = format!(
        "{title}  (mean ± 1σ over {n} run{})",
        if n == 1 { "" } else { "s" }
    );
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(caption, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(56)
        .y_label_area_size(96);
    // A log axis is drawn as a linear axis of log10 values, labelled with the values: plotters'
    // own log scale labels only the top decade of a narrow range.
    let (y0, y1, map): (f64, f64, Box<dyn Fn(f64) -> f64>) = if log_y {
        let (l, h) = ((lo * 0.8).log10(), (hi * 1.25).log10());
        (l, h, Box::new(move |v: f64| v.max(lo * 0.8).log10()))
    } else {
        let pad = 0.05 * (hi - lo).max(1e-12);
        (lo - pad, hi + pad, Box::new(|v| v))
    };
    let mut chart = builder
        .build_cartesian_2d(0.0..tmax, y0..y1)
        .map_err(draw_err)?;
    let log = log_y;
    let fmt = move |v: &f64| {
        if log {
            format!("{:.1e}", 10f64.powf(*v))
        } else {
            format!("{v:.3}")
        }
    };
    chart
        .configure_mesh()
        .x_desc("time [s]")
        .y_desc(if log {
            format!("{} (log scale)", metric_label(metric))
        } else {
            metric_label(metric).to_string()
        })
        .y_labels(12)
        .y_label_formatter(&fmt)
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()
        .map_err(draw_err)?;
    let series: Vec<(String, &edgekf::sim::Series)> =
        series.iter().map(|(l, s)| (l.clone(), s)).collect();
    draw_bands(&mut chart, &t, &series, &map)?;
    root.present().map_err(draw_err)?;
    Ok(())
}

/// The legend of every line figure: upper right, on a translucent white box.
fn draw_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    font_size: u32,
) -> Result<()> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", font_size))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(draw_err)?;
    Ok(())
}

/// Mean curves with ±1σ bands (values mapped to the axis by `map`) and the legend.
fn draw_bands<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    t: &[f64],
    series: &[(String, &edgekf::sim::Series)],
    map: &dyn Fn(f64) -> f64,
) -> Result<()> {
    let sd = |v: &f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
    for (k, (l, s)) in series.iter().enumerate() {
        let c = colour(k);
        let upper = t
            .iter()
            .zip(s.mean.iter().zip(&s.std))
            .map(|(&x, (m, v))| (x, map(m + sd(v))));
        let lower = t
            .iter()
            .zip(s.mean.iter().zip(&s.std))
            .rev()
            .map(|(&x, (m, v))| (x, map(m - sd(v))));
        let band: Vec<(f64, f64)> = upper.chain(lower).collect();
        chart
            .draw_series(std::iter::once(Polygon::new(band, c.mix(0.18).filled())))
            .map_err(draw_err)?;
        chart
            .draw_series(LineSeries::new(
                t.iter().zip(&s.mean).map(|(&x, &m)| (x, map(m))),
                c.stroke_width(2),
            ))
            .map_err(draw_err)?
            .label(l.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
    }
    draw_legend(chart, 16)
}

fn inputs_plot(
    path: &Path,
    spec: &PlotSpec,
    agent: usize,
    sc: &Scenario,
    res: &Results,
    labels: &[String],
) -> Result<()> {
    let (n, d) = (sc.framework().agents(), sc.framework().dim());
    let t: Vec<f64> = res.steps.iter().map(|&k| k as f64 * res.dt).collect();
    let tmax = *t.last().unwrap_or(&1.0);
    let mut curves = Vec::new();
    for l in labels {
        let e = res
            .estimator(l)
            .ok_or_else(|| anyhow!("no estimator `{l}`"))?;
        let reports = e.inputs.len() / (n * d);
        for c in 0..d {
            let v: Vec<f64> = (0..reports)
                .map(|k| e.inputs[k * n * d + agent * d + c])
                .collect();
            curves.push((format!("{l}: u_{}", ["x", "y", "z"][c]), v));
        }
    }
    let root = BitMapBackend::new(path, (1100, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(draw_err)?;
    let title = if spec.title().is_empty() {
        "control input".to_string()
    } else {
        spec.title().to_string()
    };
    let root = root
        .titled(
            &format!("{title}  (agent {agent}, run {})", sc.paths_run()),
            ("sans-serif", 24),
        )
        .map_err(draw_err)?;
    let (top, bottom) = root.split_vertically(430);
    // Whole run, then the steady state (last five sixths) on its own scale: the first second's
    // inputs are two orders of magnitude larger than the steady-state process.
    let t_steady = tmax / 6.0;
    for (area, from, caption) in [
        (&top, 0.0, "whole run"),
        (&bottom, t_steady, "steady state"),
    ] {
        let first = t.iter().position(|&x| x >= from).unwrap_or(0);
        let (lo, hi) = curves
            .iter()
            .flat_map(|(_, v)| v[first..].iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let pad = 0.05 * (hi - lo).max(1e-12);
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{caption} ({:.0}–{:.0} s)", t[first], tmax),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d(t[first]..tmax, (lo - pad)..(hi + pad))
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc("control input u [m/s]")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .draw()
            .map_err(draw_err)?;
        for (k, (l, v)) in curves.iter().enumerate() {
            let c = colour(k);
            chart
                .draw_series(LineSeries::new(
                    t[first..].iter().copied().zip(v[first..].iter().copied()),
                    c.stroke_width(1),
                ))
                .map_err(draw_err)?
                .label(l.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3))
                });
        }
        draw_legend(&mut chart, 15)?;
    }
    root.present().map_err(draw_err)?;
    Ok(())
}

fn paths_plot(
    path: &Path,
    spec: &PlotSpec,
    sc: &Scenario,
    res: &Results,
    labels: &[String],
) -> Result<()> {
    let fw = sc.framework();
    let (n, d) = (fw.agents(), fw.dim());
    let panels = labels.len().max(1);
    let cols = panels.min(2);
    let rows = panels.div_ceil(cols);
    let root =
        BitMapBackend::new(path, (640 * cols as u32, 600 * rows as u32 + 80)).into_drawing_area();
    root.fill(&WHITE).map_err(draw_err)?;
    let title = if spec.title().is_empty() {
        "agent paths".to_string()
    } else {
        spec.title().to_string()
    };
    let root = root.titled(&title, ("sans-serif", 22)).map_err(draw_err)?;
    let (root, foot) = root.split_vertically(600 * rows as u32 + 80 - 30 - 26);
    foot.draw(&Text::new(
        format!(
            "run {}, 0–{:.0} s; ○ start, ▲ end (red: leaders), grey: final links",
            sc.paths_run(),
            res.steps.last().copied().unwrap_or(0) as f64 * res.dt
        ),
        (20, 4),
        ("sans-serif", 16),
    ))
    .map_err(draw_err)?;
    let areas = root.split_evenly((rows, cols));
    for (area, label) in areas.iter().zip(labels) {
        let e = res
            .estimator(label)
            .ok_or_else(|| anyhow!("no estimator `{label}`"))?;
        let p = &e.paths;
        let nr = p.len() / (n * d);
        if nr == 0 {
            continue;
        }
        let at = |k: usize, i: usize, c: usize| p[k * n * d + i * d + c];
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for k in 0..nr {
            for i in 0..n {
                x0 = x0.min(at(k, i, 0));
                x1 = x1.max(at(k, i, 0));
                let y = if d > 1 { at(k, i, 1) } else { 0.0 };
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        // Equal aspect ratio.
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        let half = 0.55 * (x1 - x0).max(y1 - y0).max(1e-9);
        let mut chart = ChartBuilder::on(area)
            .caption(label.as_str(), ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d((cx - half)..(cx + half), (cy - half)..(cy + half))
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("x [m]")
            .y_desc("y [m]")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(draw_err)?;
        let y = |k: usize, i: usize| if d > 1 { at(k, i, 1) } else { 0.0 };
        let last = nr - 1;
        for &(i, j) in fw.graph().links() {
            chart
                .draw_series(LineSeries::new(
                    vec![(at(last, i, 0), y(last, i)), (at(last, j, 0), y(last, j))],
                    BLACK.mix(0.35),
                ))
                .map_err(draw_err)?;
        }
        for i in 0..n {
            let c = colour(i);
            chart
                .draw_series(LineSeries::new(
                    (0..nr).map(|k| (at(k, i, 0), y(k, i))),
                    c.stroke_width(1),
                ))
                .map_err(draw_err)?;
            chart
                .draw_series(std::iter::once(Circle::new(
                    (at(0, i, 0), y(0, i)),
                    4,
                    c.stroke_width(2),
                )))
                .map_err(draw_err)?;
            let leader = fw.leaders().contains(&i);
            let style = if leader { RED.filled() } else { c.filled() };
            chart
                .draw_series(std::iter::once(TriangleMarker::new(
                    (at(last, i, 0), y(last, i)),
                    7,
                    style,
                )))
                .map_err(draw_err)?;
        }
    }
    root.present().map_err(draw_err)?;
    Ok(())
}
