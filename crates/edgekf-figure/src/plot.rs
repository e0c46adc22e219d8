//! The figures of a filter study, drawn with the figure toolkit (`crate::figure`): a metric over
//! time, agent paths, one agent's inputs.
//!
//! Whole-figure conventions:
//! - a metric is drawn as its mean over the runs with a translucent ±1σ band; a quantity that is
//!   the same in every run (a shared-gain filter's covariance trace) is drawn as a plain line and
//!   the note under the figure says it is deterministic — never "mean ± 1σ" for it;
//! - each estimator keeps its colour (its position in the study) in every figure of the study;
//! - curves that coincide are drawn with distinct dashes and markers, the legend says so, and a
//!   panel of their differences is added under the plot;
//! - `log_x` gives a log-time axis, `inset = [from, to]` a zoomed inset, for transients that a
//!   linear 0–30 s axis squeezes into its first pixels;
//! - legends carry maths markup (`P_{fail}`, `û^{j}`) from the plot's `legend` table;
//! - paths use the agent palette (never the grey of the final links), at the reports kept by
//!   `paths_per_decade`, exactly the rows of `paths.csv`.

use std::path::Path;

use edgekf::framework::Framework;
use edgekf::scenario::{PlotSpec, Scenario};
use edgekf::sim::{Outcome, Results};

use crate::{
    coincide, palette, Axis, CoincideGroup, Curve, Dash, Figure, HAlign, Inset, Label, LegendMode,
    Marker, Panel, RenderReport, Shape, StudyFigureError, Style, VAlign,
};

/// Curves closer than this many pixels (vertically) look like one line.
const SAME_PX: f64 = 3.0;
/// ... when they are that close at this share of the reported times.
const SAME_SHARE: f64 = 0.9;
/// Height of a metric figure's plot area, roughly, in pixels (720 px figure).
const PLOT_PX: f64 = 500.0;
/// Markers for the members of a group of coinciding curves, in order.
const GROUP_SHAPES: [Shape; 6] = [
    Shape::Circle,
    Shape::Square,
    Shape::TriangleUp,
    Shape::Diamond,
    Shape::TriangleDown,
    Shape::Cross,
];

/// A group of curves that look like one line, and the share of the times at which they do.
struct VisualGroup {
    group: CoincideGroup,
    share: f64,
}

/// `12 %`, `0.4 %`, `0.03 %`.
fn pct(v: f64) -> String {
    let p = 100.0 * v;
    if p >= 10.0 {
        format!("{p:.0} %")
    } else if p >= 1.0 {
        format!("{p:.1} %")
    } else {
        format!("{p:.2} %")
    }
}

/// Groups of curves (on one time grid) that a reader cannot tell apart: within `SAME_PX` pixels
/// of each other at `SAME_SHARE` of their common points, on a plot `plot_px` high. Unlike the
/// toolkit's strict test (every point within 0.1 %), this also catches curves that part only in
/// a short transient — e.g. thesis Fig. 6.2's five P_fail curves, 6.6 % apart at 0.08 s and
/// within 0.2 % elsewhere.
fn visual_groups(curves: &[Curve], log_y: bool, plot_px: f64) -> Vec<VisualGroup> {
    let usable = |v: f64| v.is_finite() && (!log_y || v > 0.0);
    let (lo, hi) = curves
        .iter()
        .flat_map(|c| c.y.iter().copied().filter(|&v| usable(v)))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    // SAME_PX pixels as a relative difference (log axis) or a share of the span (linear).
    let span = (hi - lo).max(f64::MIN_POSITIVE);
    let tol = if log_y {
        let decades = (hi / lo).log10().max(0.3);
        10f64.powf(SAME_PX / plot_px * decades) - 1.0
    } else {
        SAME_PX / plot_px
    };
    let dev = |a: f64, b: f64| {
        if log_y {
            (a - b).abs() / a.abs().max(b.abs())
        } else {
            (a - b).abs() / span
        }
    };
    // (share of points within tol, max deviation) between curves i and j.
    let pair = |i: usize, j: usize| -> Option<(f64, f64)> {
        let (a, b) = (&curves[i], &curves[j]);
        let n = a.y.len().min(b.y.len());
        if n < 2 || a.x[..n] != b.x[..n] {
            return None;
        }
        let (mut within, mut count, mut worst) = (0usize, 0usize, 0.0f64);
        for k in 0..n {
            let (p, q) = (a.y[k], b.y[k]);
            if usable(p) && usable(q) {
                let d = dev(p, q);
                count += 1;
                within += usize::from(d <= tol);
                worst = worst.max(d);
            }
        }
        (count >= 2).then(|| (within as f64 / count as f64, worst))
    };
    let n = curves.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for i in 0..n {
        for j in 0..i {
            if pair(i, j).is_some_and(|(share, _)| share >= SAME_SHARE) {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
            }
        }
    }
    let mut out = Vec::new();
    for r in 0..n {
        let members: Vec<usize> = (0..n).filter(|&i| root(&mut parent, i) == r).collect();
        if members.len() < 2 {
            continue;
        }
        let (mut share, mut worst) = (1.0f64, 0.0f64);
        for (x, &i) in members.iter().enumerate() {
            for &j in &members[..x] {
                if let Some((s, w)) = pair(i, j) {
                    share = share.min(s);
                    worst = worst.max(w);
                }
            }
        }
        out.push(VisualGroup {
            group: CoincideGroup {
                labels: members.iter().map(|&i| curves[i].label.clone()).collect(),
                members,
                tolerance: tol,
                max_deviation: worst,
            },
            share,
        });
    }
    out
}

/// Axis label (with markup) and unit of a metric.
pub fn metric_axis(metric: &str) -> (String, &'static str) {
    let (l, u) = match metric {
        "est_error" => ("estimation error ε_{k} = ‖x_{k} − x̂_{k|k}‖", "m"),
        "est_error_sq" => ("squared estimation error ε_{k}²", "m²"),
        "cov_trace" => ("trace of the posterior covariance tr Σ_{k|k}", "m²"),
        "procrustes" => ("Procrustes error", "m"),
        "tracking_error" => ("tracking error δ_{k}", "m²"),
        "edge_cov_trace" => ("position trace of one edge's covariance", "m²"),
        "psi" => ("convergence indicator ψ", ""),
        "theta_error" => ("consensus error ‖Θ̂_{i} − Θ^{*}‖²_{F}", ""),
        "theta_ral_error" => ("RAL error ‖Θ̂_{i} − Θ^{*}‖²_{F}", ""),
        "pcrb_trace" => ("trace of the PCRB", "m²"),
        other => (other, ""),
    };
    (l.to_string(), u)
}

/// The unit of a metric (`""` for a dimensionless one), for tables.
pub fn metric_unit(metric: &str) -> &'static str {
    metric_axis(metric).1
}

/// Writes the abnormal findings of a render (non-finite values, clamped ranges) to stderr; the
/// figure carries the same as a note.
fn warn(path: &Path, rep: &RenderReport) {
    for w in rep.problems() {
        eprintln!("warning: {}: {w}", path.display());
    }
}

/// Renders one figure request into `path` (a PNG; the caller stages it under a temporary name).
/// Estimators without data for the figure (e.g. diverged before its first point) are left out,
/// and the figure says so.
///
/// # Errors
/// [`StudyFigureError::Draw`] when the PNG cannot be written.
pub fn render(
    path: &Path,
    spec: &PlotSpec,
    sc: &Scenario,
    res: &Results,
) -> Result<(), StudyFigureError> {
    let fig = figure(spec, sc, res);
    let rep = fig.render(path).map_err(|source| StudyFigureError::Draw {
        path: path.to_path_buf(),
        source,
    })?;
    warn(path, &rep);
    Ok(())
}

/// The figure of one plot request, not yet drawn.
pub fn figure(spec: &PlotSpec, sc: &Scenario, res: &Results) -> Figure {
    let labels: Vec<String> = spec
        .estimators()
        .map(<[String]>::to_vec)
        .unwrap_or_else(|| res.labels().iter().map(|s| s.to_string()).collect());
    match spec {
        PlotSpec::Metric {
            metric,
            log_x,
            ratio_to: Some(reference),
            ..
        } => ratio_figure(spec, metric, reference, *log_x, res, &labels),
        PlotSpec::Metric {
            metric,
            log_y,
            log_x,
            inset,
            ..
        } => metric_figure(spec, metric, *log_y, *log_x, *inset, res, &labels),
        PlotSpec::Inputs { agent, .. } => inputs_figure(spec, *agent, sc, res, &labels),
        PlotSpec::Paths { .. } => paths_figure(spec, sc, res, &labels),
        // Sweeps and GA-RKF figures are drawn by `crate::plot_garkf` (the caller routes them there).
        PlotSpec::Panels { .. } | PlotSpec::Summary { .. } | PlotSpec::Indicator { .. } => {
            Figure::new(title_of(spec, spec.file())).with_note(format!(
                "{} is drawn by the GA-RKF figures module",
                spec.file()
            ))
        }
    }
}

/// The colour of estimator `label`: its position in the study, so it is the same in every figure.
fn colour_of(res: &Results, label: &str) -> crate::Rgb {
    palette::series(
        res.estimators
            .iter()
            .position(|e| e.label == label)
            .unwrap_or(0),
    )
}

/// The time axis: logarithmic from the first report (`log_x`), else linear from 0 to the last
/// report (so that 0 is labelled).
fn time_axis(res: &Results, log_x: bool) -> Axis {
    if log_x {
        return Axis::log("time t", "s").tight();
    }
    let end = res.steps.last().copied().unwrap_or(1) as f64 * res.dt;
    Axis::linear("time t", "s").with_range(0.0, end)
}

/// Times of the reported steps [s].
fn times(res: &Results) -> Vec<f64> {
    res.steps.iter().map(|&k| k as f64 * res.dt).collect()
}

/// A short time for notes and titles (`0.25 s`, `30 s`).
fn secs(t: f64) -> String {
    let s = format!("{t:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    format!("{s} s")
}

/// The title of a plot: its own, or a default.
fn title_of(spec: &PlotSpec, default: &str) -> String {
    if spec.title().is_empty() {
        default.to_string()
    } else {
        spec.title().to_string()
    }
}

/// Notes on estimators that stopped early.
fn divergence_notes(res: &Results, labels: &[String]) -> Vec<String> {
    labels
        .iter()
        .filter_map(|l| res.estimator(l))
        .filter_map(|e| match &e.outcome {
            Outcome::Diverged { step, .. } => Some(format!(
                "{} diverged at t = {} (step {step}); its curve ends there (see status.csv).",
                e.label,
                secs(*step as f64 * res.dt)
            )),
            Outcome::Completed => None,
        })
        .collect()
}

/// Each estimator's `metric` over `reference`'s, paired run by run: the ratio in every run at
/// every report, then its mean ± 1 standard error over the runs, with the line of equality.
fn ratio_figure(
    spec: &PlotSpec,
    metric: &str,
    reference: &str,
    log_x: bool,
    res: &Results,
    labels: &[String],
) -> Figure {
    let t = times(res);
    let runs = res.runs.len();
    let (ylabel, _) = metric_axis(metric);
    let x_axis = time_axis(res, log_x);
    let base = spec.legend_text(reference).to_string();
    let mut panel = Panel::new(
        x_axis,
        Axis::linear(format!("{ylabel}, over {base}'s in the same run"), ""),
    );
    panel.coincide_tolerance = None;
    let valid = |l: &str| res.estimator(l).map_or(0, |e| e.valid);
    let (Some(den), nr) = (res.values(reference, metric), valid(reference)) else {
        return Figure::single(title_of(spec, metric), panel)
            .with_note(format!("No `{metric}` for {reference}."));
    };
    for l in labels.iter().filter(|l| *l != reference) {
        let Some(num) = res.values(l, metric) else {
            continue;
        };
        let n = nr.min(valid(l));
        let (mut mean, mut lo, mut hi) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..n {
            let r: Vec<f64> = (0..runs)
                .map(|j| num[k * runs + j] / den[k * runs + j])
                .collect();
            let r: Vec<f64> = r.into_iter().filter(|v| v.is_finite()).collect();
            let m = r.iter().sum::<f64>() / r.len().max(1) as f64;
            let se = if r.len() > 1 {
                let var = r.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (r.len() - 1) as f64;
                (var / r.len() as f64).sqrt()
            } else {
                0.0
            };
            mean.push(m);
            lo.push(m - se);
            hi.push(m + se);
        }
        let c = Curve::new(spec.legend_text(l).to_string(), t[..n].to_vec(), mean)
            .with_style(Style::line().colour(colour_of(res, l)))
            .with_band(lo, hi);
        panel.curves.push(c);
    }
    let (t0, t1) = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0),
    );
    panel.curves.push(
        Curve::new("equal (ratio 1)", vec![t0, t1], vec![1.0, 1.0]).with_style(
            Style::line()
                .colour(palette::MARKER)
                .dash(Dash::Dashed)
                .width(1.0),
        ),
    );
    let mut notes = vec![format!(
        "The ratio in each of the {runs} runs (the estimators share each run's draws), then its \
         mean ± 1 standard error over the runs (std / √{runs}): below 1, lower than {base}."
    )];
    notes.extend(divergence_notes(res, labels));
    let mut fig = Figure::single(title_of(spec, metric), panel);
    fig.notes = notes;
    fig
}

fn metric_figure(
    spec: &PlotSpec,
    metric: &str,
    log_y: bool,
    log_x: bool,
    inset: Option<[f64; 2]>,
    res: &Results,
    labels: &[String],
) -> Figure {
    let t = times(res);
    let runs = res.runs.len();
    let (ylabel, yunit) = metric_axis(metric);
    let x_axis = time_axis(res, log_x);
    let y_axis = if log_y {
        Axis::log(ylabel, yunit)
    } else {
        Axis::linear(ylabel, yunit)
    };
    let mut panel = Panel::new(x_axis, y_axis);
    let (mut banded, mut fixed, mut missing) = (Vec::new(), Vec::new(), Vec::new());
    for l in labels {
        let Some(s) = res.series(l, metric).filter(|s| !s.mean.is_empty()) else {
            missing.push(l.clone());
            continue;
        };
        let n = s.mean.len();
        let text = spec.legend_text(l).to_string();
        let style = Style::line().colour(colour_of(res, l));
        // Exactly 0 at every report: every run holds the same value (stats::mean_std).
        let deterministic = runs > 1 && s.std.iter().all(|v| *v == 0.0);
        let mut c = Curve::new(text, t[..n].to_vec(), s.mean.clone()).with_style(style);
        if runs > 1 && !deterministic {
            let sd = |v: &f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
            let lower = s.mean.iter().zip(&s.std).map(|(m, v)| m - sd(v)).collect();
            let upper = s.mean.iter().zip(&s.std).map(|(m, v)| m + sd(v)).collect();
            c = c.with_band(lower, upper);
            banded.push(l.clone());
        } else if runs > 1 {
            fixed.push(l.clone());
        }
        panel.curves.push(c);
    }
    if let Some([a, b]) = inset {
        panel = panel.with_inset(Inset::new(a, b, format!("{}–{}", secs(a), secs(b))));
    }
    let mut notes = Vec::new();
    let name = |v: &[String]| {
        v.iter()
            .map(|l| spec.legend_text(l).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match (runs, banded.is_empty(), fixed.is_empty()) {
        (1, _, _) => notes.push("One run (no spread to show).".to_string()),
        (_, false, true) => notes.push(format!("Mean over {runs} Monte Carlo runs, ±1σ shaded.")),
        (_, true, false) => notes.push(format!(
            "Deterministic: identical in all {runs} runs (the filters' gains do not depend on \
             the data), so there is no spread to shade."
        )),
        (_, false, false) => notes.push(format!(
            "Mean over {runs} Monte Carlo runs, ±1σ shaded; {} identical in every run \
             (deterministic, no band).",
            name(&fixed)
        )),
        (_, true, true) => {}
    }
    if log_x {
        notes.push(format!(
            "Log time axis from the first step (t = {}), so the transient is visible.",
            secs(t.first().copied().unwrap_or(res.dt))
        ));
    }
    if !missing.is_empty() {
        notes.push(format!("No data for {}.", name(&missing)));
    }
    notes.extend(divergence_notes(res, labels));
    panel.coincide_tolerance = None;
    let groups = visual_groups(&panel.curves, log_y, PLOT_PX);
    for g in &groups {
        for (m, &i) in g.group.members.iter().enumerate() {
            let st = &mut panel.curves[i].style;
            st.dash = Some(Dash::ALL[m % Dash::ALL.len()]);
            st.marker = Some(
                Marker::new(GROUP_SHAPES[m % GROUP_SHAPES.len()], 7.0)
                    .spaced(90.0, 90.0 * (m as f64 + 0.5) / g.group.members.len() as f64),
            );
        }
    }
    let title = title_of(spec, metric);
    let mut fig = if groups.is_empty() {
        Figure::single(title, panel)
    } else {
        let diffs: Vec<Panel> = groups
            .iter()
            .map(|g| {
                // The group's name in the title while it fits the panel's width (the note
                // below the figure names every member either way).
                let name = coincide::group_name(&g.group.labels);
                let which = if name.chars().count() <= 70 {
                    name
                } else {
                    format!("{} curves, named below", g.group.members.len())
                };
                let mut d = panel.difference_panel(&g.group).with_title(format!(
                    "differences within the coinciding curves ({which})"
                ));
                d.inset = None;
                d
            })
            .collect();
        for (g, d) in groups.iter().zip(&diffs) {
            let of = if log_y { "" } else { " of the axis span" };
            // The largest difference the lower panel draws, in its own terms (relative to the
            // first curve on a log axis), so that the note and the panel say the same number.
            let largest = d
                .curves
                .iter()
                .flat_map(|c| c.y.iter())
                .filter(|v| v.is_finite())
                .fold(0.0_f64, |m, v| m.max(v.abs()));
            let shown = if log_y {
                pct(largest)
            } else {
                format!("{largest:.3e}{}", unit_suffix(&panel.y_axis.unit))
            };
            notes.push(format!(
                "{} coincide to within {}{of} ({} px) at {:.0} % of the reported times: dashes \
                 and markers tell them apart; the lower panel shows their differences (largest \
                 {shown}).",
                coincide::group_name(&g.group.labels),
                pct(g.group.tolerance),
                SAME_PX,
                100.0 * g.share,
            ));
        }
        let mut f = Figure::new(title).with_size(1100, 720 + 330 * groups.len() as u32);
        f.panels.push(panel);
        f.panels.extend(diffs);
        f
    };
    fig.notes = notes;
    fig
}

fn inputs_figure(
    spec: &PlotSpec,
    agent: usize,
    sc: &Scenario,
    res: &Results,
    labels: &[String],
) -> Figure {
    let (n, d) = (sc.framework().agents(), sc.framework().dim());
    let t = times(res);
    let tmax = t.last().copied().unwrap_or(res.dt);
    let axes = ["x", "y", "z"];
    let many = labels.len() > 1;
    let mut curves = Vec::new();
    for l in labels {
        let Some(e) = res.estimator(l) else { continue };
        let reports = (e.inputs.len() / (n * d).max(1)).min(t.len());
        for (c, axis) in axes.iter().enumerate().take(d) {
            let v: Vec<f64> = (0..reports)
                .map(|k| e.inputs[k * n * d + agent * d + c])
                .collect();
            let name = if many {
                format!("{}: u_{{{axis}}}", spec.legend_text(l))
            } else {
                format!("u_{{{axis}}}")
            };
            let colour = palette::series(curves.len());
            curves.push(
                Curve::new(name, t[..reports].to_vec(), v)
                    .with_style(Style::line().colour(colour).width(1.0)),
            );
        }
    }
    // The transient, then the steady state, each on its own scale: the first second's inputs are
    // two orders of magnitude larger than the steady-state process (on one axis for the whole
    // run the transient is a spike in the first pixels and the steady state a flat line).
    let from = tmax / 6.0;
    let part = |a: f64, b: f64| -> Vec<Curve> {
        curves
            .iter()
            .map(|c| {
                let (i, j) = (
                    c.x.partition_point(|&x| x < a),
                    c.x.partition_point(|&x| x <= b),
                );
                Curve {
                    x: c.x[i..j].to_vec(),
                    y: c.y[i..j].to_vec(),
                    ..c.clone()
                }
            })
            .collect()
    };
    let axis = || Axis::linear(format!("control input u^{{{agent}}}_{{k}}"), "m/s");
    let mut whole = Panel::new(Axis::linear("time t", "s").with_range(0.0, from), axis())
        .with_title(format!("transient (0–{})", secs(from)));
    whole.curves = part(0.0, from);
    let mut late = Panel::new(Axis::linear("time t", "s").with_range(from, tmax), axis())
        .with_title(format!("steady state ({}–{})", secs(from), secs(tmax)));
    late.curves = part(from, tmax);
    for p in [&mut whole, &mut late] {
        // Two coordinates of one noisy signal are not "coinciding curves".
        p.coincide_tolerance = None;
    }
    let mut fig = Figure::new(title_of(spec, "control input")).with_size(1100, 900);
    fig.panels = vec![whole, late];
    fig.notes = vec![format!(
        "Agent {agent}, run {} (one realisation), every reported step ({} values).",
        sc.paths_run(),
        t.len()
    )];
    fig.notes.extend(divergence_notes(res, labels));
    fig
}

/// The paths of every estimator's loop: one panel per estimator in 2-D; in 3-D, three
/// orthographic views (x–y, x–z, y–z) per estimator, one row each.
fn paths_figure(spec: &PlotSpec, sc: &Scenario, res: &Results, labels: &[String]) -> Figure {
    let fw = sc.framework();
    let (n, d) = (fw.agents(), fw.dim());
    let keep = sc.path_reports();
    let views: &[(usize, usize)] = if d >= 3 {
        &[(0, 1), (0, 2), (1, 2)]
    } else {
        &[(0, 1)]
    };
    let mut panels = Vec::new();
    for label in labels {
        let Some(e) = res.estimator(label) else {
            continue;
        };
        let reports = e.paths.len() / (n * d).max(1);
        let idx: Vec<usize> = keep.iter().copied().filter(|&k| k < reports).collect();
        for &view in views {
            let mut title = spec.legend_text(label).to_string();
            if d >= 3 {
                title = format!("{title} — {}–{} view", AXES[view.0], AXES[view.1]);
            }
            let mut panel = path_panel(title, &e.paths, fw, &idx, view);
            if d >= 3 {
                // A legend per view would crowd them, and one placed beside a view squeezes
                // it: the note below says what the marks are.
                panel.legend = LegendMode::Hidden;
            }
            panels.push(panel);
        }
    }
    let cols = if d >= 3 { 3 } else { panels.len().clamp(1, 2) };
    let rows = panels.len().div_ceil(cols).max(1);
    let (w, h) = if d >= 3 { (480, 470) } else { (620, 560) };
    let mut fig = Figure::new(title_of(spec, "agent paths"))
        .with_size(w * cols as u32 + 40, h * rows as u32 + 110);
    fig.columns = cols;
    fig.panels = panels;
    let tmax = res.steps.last().copied().unwrap_or(0) as f64 * res.dt;
    let shown = keep.len();
    let every = if shown == res.steps.len() {
        "every reported step".to_string()
    } else {
        format!("{shown} log-spaced reports of {}", res.steps.len())
    };
    fig.notes = vec![format!(
        "Run {}, 0–{}, positions at {every} (as in paths.csv); agent colours by index{}{}; final \
         links grey; ○ start, ▲ end (red: leaders){}.",
        sc.paths_run(),
        secs(tmax),
        if n > 9 { ", agents 9+ dashed" } else { "" },
        if n > MAX_LABELLED {
            format!(" (numbered up to {MAX_LABELLED} agents)")
        } else {
            String::new()
        },
        if d >= 3 {
            "; 3-D: each row one estimator seen along z, y and x (orthographic)"
        } else {
            ""
        }
    )];
    fig.notes.extend(divergence_notes(res, labels));
    fig
}

/// Paths figures number the agents up to this many.
const MAX_LABELLED: usize = 30;

/// The coordinate names of the views.
const AXES: [&str; 3] = ["x", "y", "z"];

/// One view of one loop's paths: coordinates `view.0` and `view.1` of the reports `idx` of
/// `paths` (report-major, then agent, then coordinate), the final links, start and end markers.
fn path_panel(
    title: String,
    paths: &[f64],
    fw: &Framework,
    idx: &[usize],
    view: (usize, usize),
) -> Panel {
    let (n, d) = (fw.agents(), fw.dim());
    let (a, b) = view;
    let mut p =
        Panel::new(Axis::linear(AXES[a], "m"), Axis::linear(AXES[b], "m")).with_title(title);
    p.equal_aspect = true;
    p.coincide_tolerance = None;
    let (Some(&first), Some(&last)) = (idx.first(), idx.last()) else {
        return p;
    };
    let at = |k: usize, i: usize, c: usize| {
        if c < d {
            paths[k * n * d + i * d + c]
        } else {
            0.0
        }
    };
    let point = |k: usize, i: usize| (at(k, i, a), at(k, i, b));
    for &(i, j) in fw.graph().links() {
        let ((xi, yi), (xj, yj)) = (point(last, i), point(last, j));
        p.curves.push(
            Curve::new("final links", vec![xi, xj], vec![yi, yj])
                .with_style(Style::line().colour(palette::LINK).width(1.2)),
        );
    }
    for i in 0..n {
        let (colour, dash) = palette::agent(i);
        let (x, y): (Vec<f64>, Vec<f64>) = idx.iter().map(|&k| point(k, i)).unzip();
        p.curves.push(
            Curve::new("", x, y).with_style(Style::line().colour(colour).dash(dash).width(1.4)),
        );
    }
    let (sx, sy): (Vec<f64>, Vec<f64>) = (0..n).map(|i| point(first, i)).unzip();
    p.curves.push(Curve::new("start", sx, sy).with_style(
        Style::markers(Marker::new(Shape::Circle, 8.0).hollow()).colour(palette::MARKER),
    ));
    let leaders = fw.leaders();
    let (fx, fy): (Vec<f64>, Vec<f64>) = (0..n)
        .filter(|i| !leaders.contains(i))
        .map(|i| point(last, i))
        .unzip();
    p.curves.push(
        Curve::new("end", fx, fy).with_style(
            Style::markers(Marker::new(Shape::TriangleUp, 10.0)).colour(palette::MARKER),
        ),
    );
    if !leaders.is_empty() {
        let (lx, ly): (Vec<f64>, Vec<f64>) = leaders.iter().map(|&i| point(last, i)).unzip();
        p.curves
            .push(Curve::new("end (leaders)", lx, ly).with_style(
                Style::markers(Marker::new(Shape::TriangleUp, 11.0)).colour(palette::LEADER),
            ));
    }
    // Agent numbers where they can be read (every shipped paths figure has at most 11 agents).
    for i in (0..n).filter(|_| n <= MAX_LABELLED) {
        let (x, y) = point(last, i);
        p.labels.push(Label {
            offset: (7.0, -6.0),
            h: HAlign::Left,
            v: VAlign::Bottom,
            size: 13.0,
            ..Label::new(x, y, format!("{i}"))
        });
    }
    p.legend = LegendMode::Auto;
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use edgekf_io::reproductions::ENTRIES;
    use std::time::{Duration, Instant};

    /// A shipped scenario at test size (the transient and the shape of every figure kept).
    fn small(file: &str) -> (Scenario, Results) {
        let e = ENTRIES.iter().find(|e| e.file == file).unwrap();
        let sc = e.scenario().unwrap();
        let runs = sc.runs().min(6);
        let sc = sc.with_size(Some(runs), Some(3000), None).unwrap();
        let res = edgekf::sim::run(&sc, &edgekf::sim::Quiet).unwrap();
        (sc, res)
    }

    fn draw(spec: &PlotSpec, sc: &Scenario, res: &Results) -> (Figure, RenderReport) {
        let fig = figure(spec, sc, res);
        let (_, rep) = fig.draw();
        (fig, rep)
    }

    #[test]
    fn every_shipped_plot_renders_quickly_without_warnings() {
        let mut files: Vec<&str> = ENTRIES
            .iter()
            .filter(|e| !e.is_slam())
            .map(|e| e.file)
            .collect();
        files.dedup();
        let mut count = 0;
        for f in files {
            let (sc, res) = small(f);
            for spec in sc.plots() {
                let t = Instant::now();
                let (fig, rep) = draw(spec, &sc, &res);
                let took = t.elapsed();
                assert!(
                    took < Duration::from_secs(10),
                    "{f}/{}: {took:?}",
                    spec.file()
                );
                assert!(
                    rep.warnings().is_empty(),
                    "{f}/{}: {:?}",
                    spec.file(),
                    rep.warnings()
                );
                for p in &rep.panels {
                    assert!(!p.curves.is_empty(), "{f}/{}: an empty panel", spec.file());
                    // Every axis text inside the image.
                    for (s, r) in &p.texts {
                        assert!(
                            r.x0 >= 0.0
                                && r.y0 >= 0.0
                                && r.x1 <= f64::from(rep.size.0)
                                && r.y1 <= f64::from(rep.size.1),
                            "{f}/{}: `{s}` at {r:?} leaves the image",
                            spec.file()
                        );
                    }
                }
                assert!(!fig.title.is_empty());
                count += 1;
            }
        }
        assert!(count >= 17, "{count} plots");
    }

    #[test]
    fn deterministic_quantities_are_not_called_mean_plus_minus_sigma() {
        let (sc, res) = small("eusipco.toml");
        let spec = sc
            .plots()
            .iter()
            .find(|p| p.file() == "eusipco-fig4a")
            .unwrap();
        let (fig, rep) = draw(spec, &sc, &res);
        let all: String = std::iter::once(fig.title.clone())
            .chain(fig.notes.clone())
            .collect::<Vec<_>>()
            .join(" ");
        assert!(!all.contains('±'), "{all}");
        assert!(all.contains("Deterministic"), "{all}");
        // No band drawn: every curve is a bare line.
        assert!(fig.panels[0].curves.iter().all(|c| c.band.is_none()));
        // The transient is on the log-time axis: the first point lies at the first step.
        assert_eq!(rep.panels[0].x_scale, crate::Scale::Log);
        // The legend covers no line (computed placement).
        let l = rep.panels[0].legend.as_ref().expect("a legend");
        assert!(
            l.covered < crate::legend::LINE_WEIGHT as u64 * 4,
            "legend covers {} at {:?}",
            l.covered,
            l.placement
        );
        // ε is random: mean ± 1σ, with bands.
        let spec = sc
            .plots()
            .iter()
            .find(|p| p.file() == "eusipco-fig4b")
            .unwrap();
        let (fig, _) = draw(spec, &sc, &res);
        assert!(
            fig.notes.iter().any(|n| n.contains("±1σ")),
            "{:?}",
            fig.notes
        );
        assert!(fig.panels[0].curves.iter().all(|c| c.band.is_some()));
    }

    #[test]
    fn thesis_fig_5_1_shows_none_and_fig_6_2_names_its_coinciding_curves() {
        let (sc, res) = small("eusipco.toml");
        let spec = sc
            .plots()
            .iter()
            .find(|p| p.file() == "thesis-fig5.1")
            .unwrap();
        let (fig, _) = draw(spec, &sc, &res);
        let labels: Vec<&str> = fig.panels[0]
            .curves
            .iter()
            .map(|c| c.label.as_str())
            .collect();
        assert!(labels.iter().any(|l| l.starts_with("none")), "{labels:?}");

        let (sc, res) = small("thesis-fig6.2.toml");
        let spec = &sc.plots()[0];
        let (fig, _) = draw(spec, &sc, &res);
        let groups = visual_groups(&fig.panels[0].curves, true, PLOT_PX);
        assert_eq!(groups.len(), 1);
        let g = &groups[0].group;
        assert_eq!(g.members.len(), 5, "{:?}", g.labels);
        assert!(
            g.labels.iter().all(|l| l.contains("P_{fail}")),
            "{:?}",
            g.labels
        );
        // Distinct dashes and markers for the members, a difference panel, and a note.
        let mut dashes: Vec<String> = g
            .members
            .iter()
            .map(|&i| format!("{:?}", fig.panels[0].curves[i].style.dash))
            .collect();
        dashes.dedup();
        assert_eq!(dashes.len(), 5);
        assert!(g
            .members
            .iter()
            .all(|&i| fig.panels[0].curves[i].style.marker.is_some()));
        assert_eq!(fig.panels.len(), 2);
        assert_eq!(fig.panels[1].curves.len(), 4);
        assert!(
            fig.notes.iter().any(|n| n.contains("coincide")),
            "{:?}",
            fig.notes
        );
        // The baseline reads as û = 0, not "u = 0".
        assert!(fig.panels[0]
            .curves
            .iter()
            .any(|c| c.label.contains("û^{j} = 0")));
    }

    /// Thesis Fig. 5.3's paired companion: each curve is the mean over the runs of the per-run
    /// ratio, its band ± 1 standard error; the reference itself is not drawn.
    #[test]
    fn a_ratio_plot_draws_the_paired_ratio_per_run() {
        let (sc, res) = small("eusipco.toml");
        let spec = sc
            .plots()
            .iter()
            .find(|p| p.file() == "thesis-fig5.3-ratio")
            .expect("shipped")
            .clone();
        let (fig, rep) = draw(&spec, &sc, &res);
        assert_eq!(rep.panels.len(), 1);
        let p = &fig.panels[0];
        let labels: Vec<&str> = p.curves.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(labels, ["rkf", "jrkf", "crkf", "equal (ratio 1)"]);
        let runs = res.runs.len();
        let (num, den) = (
            res.values("rkf", "procrustes").unwrap(),
            res.values("mle", "procrustes").unwrap(),
        );
        let k = res.steps.len() - 1;
        let r: Vec<f64> = (0..runs)
            .map(|j| num[k * runs + j] / den[k * runs + j])
            .collect();
        let m = r.iter().sum::<f64>() / runs as f64;
        let sd = (r.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
        let c = &p.curves[0];
        assert!((c.y[k] - m).abs() <= 1e-12 * m.abs(), "{} vs {m}", c.y[k]);
        let (lo, hi) = c.band.as_ref().unwrap();
        let se = sd / (runs as f64).sqrt();
        assert!((hi[k] - lo[k] - 2.0 * se).abs() <= 1e-12, "band ± 1 SE");
    }

    #[test]
    fn an_inset_is_drawn_where_asked() {
        let (sc, res) = small("thesis-fig4.8.toml");
        let PlotSpec::Metric {
            file,
            title,
            metric,
            log_y,
            log_x,
            estimators,
            legend,
            ..
        } = sc.plots()[0].clone()
        else {
            panic!("a metric plot")
        };
        let spec = PlotSpec::Metric {
            file,
            title,
            metric,
            log_y,
            log_x,
            inset: Some([0.0, 0.5]),
            estimators,
            legend,
            ratio_to: None,
        };
        let (_, rep) = draw(&spec, &sc, &res);
        assert!(rep.panels[0].inset.is_some());
        // Linear time axes start at 0 and label it.
        let first = rep.panels[0]
            .x_ticks
            .iter()
            .find(|t| t.label.is_some())
            .unwrap();
        assert!(first.value.abs() < 1e-12, "{:?}", rep.panels[0].x_ticks);
        assert!(
            matches!(first.label.as_deref(), Some("0" | "0.0")),
            "{first:?}"
        );
    }

    #[test]
    fn paths_use_agent_colours_never_the_links_grey() {
        let (sc, res) = small("thesis-fig3.3.toml");
        let spec = sc
            .plots()
            .iter()
            .find(|p| p.file() == "thesis-fig3.4")
            .unwrap();
        let (fig, _) = draw(spec, &sc, &res);
        let p = &fig.panels[0];
        for c in p.curves.iter().filter(|c| c.label.is_empty()) {
            let col = c.style.colour.unwrap();
            assert!(palette::distance(col, palette::LINK) > 70.0, "{col:?}");
            assert!(palette::chroma(col) >= 60);
        }
        // The path points are the reports kept for paths.csv.
        let agent = p.curves.iter().find(|c| c.label.is_empty()).unwrap();
        assert_eq!(agent.x.len(), sc.path_reports().len());
    }
}

#[cfg(test)]
mod group_tests {
    use super::*;

    fn c(label: &str, y: Vec<f64>) -> Curve {
        let x = (1..=y.len()).map(|k| k as f64).collect();
        Curve::new(label, x, y)
    }

    #[test]
    fn curves_apart_only_in_a_short_transient_still_look_like_one() {
        let base: Vec<f64> = (0..1000)
            .map(|k| 0.05 + (-(k as f64) / 20.0).exp())
            .collect();
        // 8 % apart over the first 30 points, 0.1 % elsewhere.
        let near: Vec<f64> = base
            .iter()
            .enumerate()
            .map(|(k, v)| v * if k < 30 { 1.08 } else { 1.001 })
            .collect();
        // 20 % apart everywhere.
        let far: Vec<f64> = base.iter().map(|v| v * 1.2).collect();
        let g = visual_groups(
            &[c("a", base.clone()), c("b", near), c("c", far)],
            true,
            500.0,
        );
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].group.members, vec![0, 1]);
        assert!(g[0].share > 0.95 && g[0].share < 0.99, "{}", g[0].share);
        assert!((g[0].group.max_deviation - 0.08 / 1.08).abs() < 1e-9);
        // On a linear axis the tolerance is a share of the span.
        let g = visual_groups(
            &[c("a", vec![0.0, 1.0]), c("b", vec![0.002, 1.002])],
            false,
            500.0,
        );
        assert_eq!(g.len(), 1);
        let g = visual_groups(
            &[c("a", vec![0.0, 1.0]), c("b", vec![0.05, 1.05])],
            false,
            500.0,
        );
        assert!(g.is_empty());
    }
}

/// " unit" for a number in a note, or nothing.
fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}
