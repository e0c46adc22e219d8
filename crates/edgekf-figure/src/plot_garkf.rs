//! The figures of sweeps and GA-RKF studies (Li & Rajan Figs 8–13), drawn with the figure
//! toolkit of this crate:
//!
//! - `panels`: a grid of metrics over time, one column per sweep value or one column, curves
//!   per estimator or per sweep value, bands ±1σ over the runs or min–max over the agents, and
//!   `tr Θ*(t)` of the maneuver as a reference (Figs 8, 10, 11 left, 12);
//! - `summary`: a sweep summary against the swept value, with the same summary of companion
//!   scenarios and then each study's graph beside it (Figs 11 right, 13a–b);
//! - `indicator`: the convergence indicator ψ against the tracking error δ with Theorem 1's
//!   bound `c̄ δ + b̄` (Fig. 9).

use std::path::Path;

use edgekf::scenario::{PlotSpec, Scenario};
use edgekf::sim::sweep::SweepResults;
use edgekf::sim::Results;

use crate::{Axis, Curve, Dash, Figure, Marker, Panel, Shape, StudyFigureError, Style};

/// What a figure may draw from besides the scenario's own results.
#[derive(Default)]
pub struct Extra<'a> {
    /// The scenario's sweep.
    pub sweep: Option<&'a SweepResults>,
    /// Companion studies of a reproduction (their scenario and sweep).
    pub companions: Vec<(&'a Scenario, &'a SweepResults)>,
}

/// Whether this module draws `spec`.
pub fn handles(spec: &PlotSpec) -> bool {
    matches!(
        spec,
        PlotSpec::Panels { .. } | PlotSpec::Summary { .. } | PlotSpec::Indicator { .. }
    )
}

/// Axis label and unit of a metric.
pub fn metric_axis(metric: &str) -> (String, &'static str) {
    let base = metric
        .trim_end_matches("_mean")
        .trim_end_matches("_min")
        .trim_end_matches("_max");
    let (label, unit) = match base {
        "tracking_error" => ("tracking error δ_{k}", "m²"),
        "edge_cov_trace" => ("tr Λ_{ij,k} (position block)", "m²"),
        "pcrb_trace" => ("PCRB (position block)", "m²"),
        "cov_trace" => ("trace of the posterior covariance", "m²"),
        "est_error" => ("estimation error ε_{k}", "m"),
        "est_error_sq" => ("squared estimation error ε_{k}²", "m²"),
        "procrustes" => ("Procrustes error", "m"),
        "psi" => ("convergence indicator ψ", ""),
        "theta_error" => ("‖Θ̂_{i} − Θ*‖²_{F} (consensus)", ""),
        "theta_ral_error" => ("‖Θ̂^{ral}_{i} − Θ*‖²_{F} (RAL)", ""),
        "theta_trace" => ("tr Θ̂_{i} (consensus)", ""),
        "theta_ral_trace" => ("tr Θ̂^{ral}_{i} (RAL)", ""),
        "stable_share" => ("share of stable runs", ""),
        other => return (other.to_string(), ""),
    };
    if metric.ends_with("_mean") && base != metric {
        (format!("time average of {label}"), unit)
    } else {
        (label.to_string(), unit)
    }
}

fn times(res: &Results) -> Vec<f64> {
    res.steps.iter().map(|&k| k as f64 * res.dt).collect()
}

/// The indices of the reports inside `window`.
fn in_window(t: &[f64], window: Option<[f64; 2]>) -> Vec<usize> {
    let (a, b) = window.map_or((f64::NEG_INFINITY, f64::INFINITY), |w| (w[0], w[1]));
    (0..t.len()).filter(|&k| t[k] >= a && t[k] <= b).collect()
}

fn pick(v: &[f64], idx: &[usize]) -> Vec<f64> {
    idx.iter()
        .map(|&k| v.get(k).copied().unwrap_or(f64::NAN))
        .collect()
}

/// One curve of `metric` for `label` in `res`, with its band.
fn metric_curve(
    res: &Results,
    label: &str,
    metric: &str,
    band: &str,
    window: Option<[f64; 2]>,
    name: String,
) -> Option<Curve> {
    let s = res.series(label, metric)?;
    let t = times(res);
    let idx: Vec<usize> = in_window(&t, window)
        .into_iter()
        .filter(|&k| k < s.mean.len())
        .collect();
    let x = pick(&t, &idx);
    let y = pick(&s.mean, &idx);
    let curve = Curve::new(name, x, y.clone());
    Some(match band {
        "std" if res.runs.len() > 1 => {
            let sd = pick(&s.std, &idx);
            let lo = y.iter().zip(&sd).map(|(m, d)| m - d).collect();
            let hi = y.iter().zip(&sd).map(|(m, d)| m + d).collect();
            curve.with_band(lo, hi)
        }
        "min-max" => {
            let lo = res.series(label, &format!("{metric}_min"))?;
            let hi = res.series(label, &format!("{metric}_max"))?;
            curve.with_band(pick(&lo.mean, &idx), pick(&hi.mean, &idx))
        }
        _ => curve,
    })
}

/// `tr Θ*(t)` of the scenario's maneuver at the reported times.
fn target_trace(sc: &Scenario, res: &Results, window: Option<[f64; 2]>) -> Option<Curve> {
    let traj = sc.trajectory()?;
    let d = sc.framework().dim();
    let t = times(res);
    let idx = in_window(&t, window);
    let x = pick(&t, &idx);
    let y = x
        .iter()
        .map(|&tt| {
            let s = traj.at(tt, d);
            (0..d).map(|a| s.theta[a * d + a]).sum()
        })
        .collect();
    Some(
        Curve::new("tr Θ*", x, y)
            .with_style(Style::line().colour(crate::Rgb::BLACK).dash(Dash::Dashed)),
    )
}

/// Renders one of this module's figures into `path`.
///
/// # Errors
/// [`StudyFigureError`] when the figure is not one of this module's, lacks the data it needs,
/// or cannot be written.
pub fn render(
    path: &Path,
    spec: &PlotSpec,
    sc: &Scenario,
    res: &Results,
    extra: &Extra<'_>,
) -> Result<(), StudyFigureError> {
    let all: Vec<String> = res.labels().iter().map(|s| s.to_string()).collect();
    let labels: Vec<String> = spec.estimators().map(<[String]>::to_vec).unwrap_or(all);
    let fig = match spec {
        PlotSpec::Panels {
            title,
            rows,
            columns,
            series,
            band,
            log_y,
            log_x,
            target_trace: tt,
            window,
            ..
        } => panels(
            sc,
            res,
            extra,
            title,
            rows,
            columns,
            series,
            band,
            (*log_x, *log_y),
            *tt,
            *window,
            &labels,
        )?,
        PlotSpec::Summary {
            title,
            metric,
            x_label,
            log_y,
            ..
        } => summary(sc, extra, title, metric, x_label, *log_y, &labels)?,
        PlotSpec::Indicator {
            title,
            estimator,
            window,
            ..
        } => indicator(sc, res, title, estimator, *window)?,
        _ => return Err(StudyFigureError::NotGarkf(spec.file().to_string())),
    };
    fig.render(path)?;
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn panels(
    sc: &Scenario,
    res: &Results,
    extra: &Extra<'_>,
    title: &str,
    rows: &[Vec<String>],
    columns: &str,
    series: &str,
    band: &str,
    (log_x, log_y): (bool, bool),
    tt: bool,
    window: Option<[f64; 2]>,
    labels: &[String],
) -> Result<Figure, StudyFigureError> {
    let sweep = extra.sweep;
    let cols: Vec<(String, &Results)> = if columns == "points" {
        let Some(sw) = sweep else {
            return Err(StudyFigureError::NoSweep);
        };
        sw.points
            .iter()
            .map(|p| (p.label.clone(), &p.results))
            .collect()
    } else {
        vec![(String::new(), res)]
    };
    let mut fig = Figure::new(title);
    fig.columns = cols.len();
    let (w, h) = (
        (560 * cols.len()).clamp(1100, 2000) as u32,
        (440 * rows.len()).clamp(720, 1400) as u32,
    );
    fig = fig.with_size(w, h);
    for row in rows {
        for (col_label, r) in &cols {
            let y_axis = {
                let (l, u) = metric_axis(&row[0]);
                if log_y {
                    Axis::log(l, u)
                } else {
                    Axis::linear(l, u)
                }
            };
            let x_axis = if log_x {
                Axis::log("time t", "s").tight()
            } else {
                Axis::linear("time t", "s").tight()
            };
            let mut panel = Panel::new(x_axis, y_axis);
            if !col_label.is_empty() {
                let param = sweep.map_or("", |s| s.parameter.as_str());
                panel.title = if col_label.contains('=') || param.is_empty() {
                    col_label.clone()
                } else {
                    format!("{param} = {col_label}")
                };
            }
            let sources: Vec<(String, &Results)> = if series == "points" {
                let Some(sw) = sweep else {
                    return Err(StudyFigureError::NoSweep);
                };
                sw.points
                    .iter()
                    .map(|p| (p.label.clone(), &p.results))
                    .collect()
            } else {
                vec![(String::new(), *r)]
            };
            for (src_label, src) in &sources {
                for l in labels {
                    for m in row {
                        let mut name = if series == "points" {
                            if labels.len() > 1 {
                                format!("{l}, {src_label}")
                            } else {
                                src_label.clone()
                            }
                        } else {
                            l.clone()
                        };
                        if row.len() > 1 {
                            name = format!("{name}: {}", short(m));
                        }
                        if let Some(mut c) = metric_curve(src, l, m, band, window, name) {
                            if row.len() > 1 && row.iter().position(|x| x == m) == Some(1) {
                                c.style = c.style.dash(Dash::Dashed);
                            }
                            panel.curves.push(c);
                        }
                    }
                }
            }
            if tt {
                if let Some(c) = target_trace(sc, r, window) {
                    panel.curves.push(c);
                }
            }
            fig.panels.push(panel);
        }
    }
    let n = res.runs.len();
    let note = match band {
        "std" => format!("mean ± 1σ over {n} run{}", if n == 1 { "" } else { "s" }),
        "min-max" => format!(
            "line: mean over the agents; band: smallest to largest agent (mean over {n} run{})",
            if n == 1 { "" } else { "s" }
        ),
        _ => format!("mean over {n} run{}", if n == 1 { "" } else { "s" }),
    };
    Ok(fig.with_note(note))
}

/// A short name of a metric for legends.
fn short(metric: &str) -> &str {
    match metric {
        "edge_cov_trace" => "tr Λ",
        "pcrb_trace" => "PCRB",
        "tracking_error" => "δ",
        "psi" => "ψ",
        other => other,
    }
}

fn summary(
    sc: &Scenario,
    extra: &Extra<'_>,
    title: &str,
    metric: &str,
    x_label: &str,
    log_y: bool,
    labels: &[String],
) -> Result<Figure, StudyFigureError> {
    let Some(sw) = extra.sweep else {
        return Err(StudyFigureError::SummaryWithoutSweep);
    };
    let share = metric.ends_with("_share");
    let y_axis = summary_axis(metric, log_y, share);
    let xl = if x_label.is_empty() {
        sw.parameter.clone()
    } else {
        x_label.to_string()
    };
    let mut panel = Panel::new(Axis::linear(xl, ""), y_axis);
    let mut studies: Vec<(String, &Scenario, &SweepResults)> = vec![(String::new(), sc, sw)];
    for (csc, csw) in &extra.companions {
        studies.push((String::new(), csc, csw));
    }
    let several = studies.len() > 1;
    let shapes = [
        Shape::Circle,
        Shape::Square,
        Shape::TriangleUp,
        Shape::Diamond,
    ];
    for (s_idx, (_, ssc, ssw)) in studies.iter().enumerate() {
        let x: Vec<f64> = ssw
            .points
            .iter()
            .enumerate()
            .map(|(k, p)| p.value.unwrap_or(k as f64))
            .collect();
        for l in labels {
            let vals = ssw.summary_of(l, metric);
            if vals.iter().all(|(m, _)| m.is_nan()) {
                continue;
            }
            let name = if several {
                // Studies told apart by their graphs (Fig. 13: sparse and dense), not file names.
                let g = ssc.framework().graph();
                let n = ssc.framework().agents();
                format!(
                    "{l}, mean degree {:.1}",
                    2.0 * g.links().len() as f64 / n as f64
                )
            } else {
                l.clone()
            };
            let marker = Marker::new(shapes[s_idx % shapes.len()], 9.0);
            let c = summary_curve(name, &x, &vals, marker, share.then(|| ssw.base.runs.len()));
            panel.curves.push(c);
        }
    }
    let n = sw.base.runs.len();
    let mut note = if share {
        format!("share of {n} runs per value, band ±1 standard error (std / √{n})")
    } else {
        format!("mean ± 1σ over {n} runs of the per-run time average")
    };
    if log_y && !share {
        if let Some(off) = clip_diverged(&mut panel) {
            note = format!("{note}; off the top (diverged, > 10⁶ × the smallest mean): {off}");
        }
    }
    let graphs: Vec<&Scenario> = studies.iter().map(|(_, ssc, _)| *ssc).collect();
    Ok(summary_figure(title, panel, &graphs, share, note))
}

/// The summary panel with its note; with several studies, their graphs (Fig. 13a) beside it
/// (Fig. 13b).
fn summary_figure(
    title: &str,
    panel: Panel,
    graphs: &[&Scenario],
    share: bool,
    note: String,
) -> Figure {
    let drawn_over = overlaps(&panel.curves, 0.05);
    let mut fig = if graphs.len() > 1 {
        let mut f = Figure::new(title).with_size(1700, 620);
        f.panels = graphs.iter().map(|ssc| graph_panel(ssc)).collect();
        let b = if share {
            "(b) the share of runs that stay stable"
        } else {
            "(b) against the swept value"
        };
        f.panels.push(panel.with_title(b));
        f.columns = f.panels.len();
        f.with_note(note)
    } else {
        Figure::single(title, panel).with_note(note)
    };
    fig.notes.extend(drawn_over);
    fig
}

/// The summary's y axis: log, or linear with a little room beyond 0 and 1 for a share (so that
/// a share of 1 is not drawn on the frame).
fn summary_axis(metric: &str, log_y: bool, share: bool) -> Axis {
    let (yl, yu) = metric_axis(metric);
    if log_y {
        Axis::log(yl, yu)
    } else if share {
        Axis::linear(yl, yu).with_range(-0.03, 1.03)
    } else {
        Axis::linear(yl, yu)
    }
}

/// One label's summary against the swept value, `vals` its (mean, std) per value, with its
/// band: for a share of `runs` runs ±1 standard error of the share (the per-run std / √runs),
/// within [0, 1]; for a time average ±1σ over the runs.
fn summary_curve(
    name: String,
    x: &[f64],
    vals: &[(f64, f64)],
    marker: Marker,
    share_of: Option<usize>,
) -> Curve {
    let y: Vec<f64> = vals.iter().map(|v| v.0).collect();
    let share = share_of.is_some();
    let scale = share_of.map_or(1.0, |runs| (runs.max(1) as f64).sqrt());
    let lo = vals
        .iter()
        .map(|(m, s)| m - s.max(0.0) / scale)
        .map(|v| if share { v.max(0.0) } else { v })
        .collect();
    let hi = vals
        .iter()
        .map(|(m, s)| m + s.max(0.0) / scale)
        .map(|v| if share { v.min(1.0) } else { v })
        .collect();
    Curve::new(name, x.to_vec(), y)
        .with_style(Style::line().marker(marker))
        .with_band(lo, hi)
}

/// Diverged loops give means hundreds of decades above the rest, which would squash every other
/// point into the bottom of a log axis: the axis keeps the rest, the bands of the points off the
/// top are left out, and the points off the top are returned, named.
fn clip_diverged(panel: &mut Panel) -> Option<String> {
    let means: Vec<f64> = panel
        .curves
        .iter()
        .flat_map(|c| c.y.iter().copied())
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let lo = means.iter().copied().fold(f64::INFINITY, f64::min);
    let top = lo * 1e6;
    let kept = means
        .iter()
        .copied()
        .filter(|v| *v <= top)
        .fold(0.0, f64::max);
    let off: Vec<String> = panel
        .curves
        .iter()
        .flat_map(|c| {
            c.x.iter()
                .zip(&c.y)
                .filter(|(_, y)| y.is_nan() || **y > top)
                .map(|(x, y)| format!("{} at {x} ({y:.1e})", c.label))
                .collect::<Vec<_>>()
        })
        .collect();
    if off.is_empty() || !lo.is_finite() || kept <= 0.0 {
        return None;
    }
    panel.y_axis = panel.y_axis.clone().with_range(lo / 3.0, kept * 10.0);
    // A diverged point's ±1σ band spans its own hundreds of decades: leave it out.
    for c in &mut panel.curves {
        if let Some((blo, bhi)) = &mut c.band {
            for (k, y) in c.y.iter().enumerate() {
                if y.is_nan() || *y > top {
                    blo[k] = f64::NAN;
                    bhi[k] = f64::NAN;
                }
            }
        }
    }
    Some(off.join(", "))
}

/// A study's framework: the agents at their configuration, its links, the leaders marked.
fn graph_panel(sc: &Scenario) -> Panel {
    let fw = sc.framework();
    let (n, d) = (fw.agents(), fw.dim());
    let at = |i: usize, c: usize| if c < d { fw.point(i)[c] } else { 0.0 };
    let links = fw.graph().links();
    let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m")).with_title(format!(
        "(a) {n} agents, {} links (mean degree {:.1})",
        links.len(),
        2.0 * links.len() as f64 / n as f64
    ));
    p.equal_aspect = true;
    p.coincide_tolerance = None;
    // Thin lines: a dense graph has over a thousand.
    let width = if links.len() > 200 { 0.4 } else { 1.0 };
    for (k, &(i, j)) in links.iter().enumerate() {
        let name = if k == 0 { "link" } else { "" };
        p.curves.push(
            Curve::new(name, vec![at(i, 0), at(j, 0)], vec![at(i, 1), at(j, 1)])
                .with_style(Style::line().colour(crate::palette::LINK).width(width)),
        );
    }
    let leaders = fw.leaders();
    let (fx, fy): (Vec<f64>, Vec<f64>) = (0..n)
        .filter(|i| !leaders.contains(i))
        .map(|i| (at(i, 0), at(i, 1)))
        .unzip();
    p.curves.push(Curve::new("follower", fx, fy).with_style(
        Style::markers(Marker::new(Shape::Circle, 6.0)).colour(crate::palette::MARKER),
    ));
    let (lx, ly): (Vec<f64>, Vec<f64>) = leaders.iter().map(|&i| (at(i, 0), at(i, 1))).unzip();
    p.curves.push(Curve::new("leader", lx, ly).with_style(
        Style::markers(Marker::new(Shape::TriangleUp, 9.0)).colour(crate::palette::LEADER),
    ));
    p
}

/// Notes for curves drawn over one another: each curve within `rel` of an earlier one at at
/// least half the values where both are finite (and at two or more), with those values.
fn overlaps(curves: &[Curve], rel: f64) -> Vec<String> {
    let mut out = Vec::new();
    for (j, b) in curves.iter().enumerate() {
        for a in &curves[..j] {
            let both: Vec<(f64, bool)> =
                a.x.iter()
                    .zip(a.y.iter().zip(&b.y))
                    .filter(|(_, (p, q))| p.is_finite() && q.is_finite())
                    .map(|(x, (p, q))| (*x, (p - q).abs() <= rel * p.abs().max(q.abs())))
                    .collect();
            let close: Vec<String> = both
                .iter()
                .filter(|c| c.1)
                .map(|c| c.0.to_string())
                .collect();
            if close.len() >= 2 && 2 * close.len() >= both.len() {
                out.push(format!(
                    "{} lies within {:.0} % of {} at {} (drawn over it).",
                    b.label,
                    100.0 * rel,
                    a.label,
                    close.join(", ")
                ));
                break;
            }
        }
    }
    out
}

fn indicator(
    sc: &Scenario,
    res: &Results,
    title: &str,
    label: &str,
    window: Option<[f64; 2]>,
) -> Result<Figure, StudyFigureError> {
    let def = sc
        .estimators()
        .iter()
        .find(|d| d.label() == label)
        .ok_or_else(|| StudyFigureError::NoEstimator(label.to_string()))?;
    let (c, b) = sc
        .theorem1_means(def.samples())
        .ok_or(StudyFigureError::NoFeasibleRal)?;
    let (Some(psi), Some(delta)) = (
        res.series(label, "psi"),
        res.series(label, "tracking_error"),
    ) else {
        return Err(StudyFigureError::NoPsiOrDelta(label.to_string()));
    };
    let t = times(res);
    let idx: Vec<usize> = in_window(&t, window)
        .into_iter()
        .filter(|&k| k < psi.mean.len())
        .collect();
    let x = pick(&t, &idx);
    let p = pick(&psi.mean, &idx);
    let d = pick(&delta.mean, &idx);
    let bound: Vec<f64> = d.iter().map(|v| c * v + b).collect();
    let left = Panel::new(
        Axis::linear("time t", "s").tight(),
        Axis::log("E[ψ] (no unit); E[δ] and the bound (m²)", ""),
    )
    .with_title("ψ and δ over time")
    .with_curve(Curve::new("E[ψ] (mean over agents)", x.clone(), p.clone()))
    .with_curve(Curve::new("E[δ] (m²)", x.clone(), d.clone()))
    .with_curve(
        Curve::new("Theorem 1: c̄ E[δ] + b̄", x, bound).with_style(Style::line().dash(Dash::Dashed)),
    );
    let cd: Vec<f64> = d.iter().map(|v| c * v).collect();
    let pb: Vec<f64> = p.iter().map(|v| v - b).collect();
    let (lo, hi) = cd
        .iter()
        .chain(&pb)
        .filter(|v| **v > 0.0 && v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), v| {
            (a.min(*v), z.max(*v))
        });
    let mut right = Panel::new(Axis::log("c̄ E[δ]", ""), Axis::log("E[ψ] − b̄", ""))
        .with_title("bias removed: below the diagonal = within the bound")
        .with_curve(
            Curve::new("E[ψ] − b̄ at each reported step", cd, pb)
                .with_style(Style::markers(Marker::new(Shape::Circle, 5.0))),
        );
    if lo.is_finite() && hi.is_finite() {
        right = right.with_curve(
            Curve::new("y = x (the bound)", vec![lo, hi], vec![lo, hi])
                .with_style(Style::line().dash(Dash::Dashed)),
        );
    }
    let mut fig = Figure::new(title).with_size(1500, 640);
    fig.columns = 2;
    let n = res.runs.len();
    Ok(fig
        .with_panel(left)
        .with_panel(right)
        .with_note(format!(
            "means over {n} runs; Theorem 1 on the nominal graph: c̄ = {c:.4}, b̄ = {b:.4e} (averages of c_i, b_i over the agents)"
        )))
}

#[cfg(test)]
mod tests {
    //! Issue 16, point 1, for this module's plot kinds (`panels`, `summary`, `indicator`): each
    //! shipped GA-RKF figure is drawn from results whose every value is pathological, without a
    //! panic and in bounded time (the toolkit's own kinds are in `tests/figure_pathological.rs`).

    use std::time::{Duration, Instant};

    use edgekf::sim::{self, Quiet};
    use edgekf_io::reproductions;

    use super::*;

    /// Value `i` of a pathological series.
    type Series = fn(usize) -> f64;

    const SERIES: &[(&str, Series)] = &[
        ("nan", |_| f64::NAN),
        ("huge", |_| 1e300),
        ("tiny", |_| 1e-300),
        ("zero", |_| 0.0),
        ("negative", |i| -1.0 - i as f64),
        ("infinite", |i| if i % 2 == 0 { f64::INFINITY } else { 1.0 }),
        (
            "alternating-huge",
            |i| if i % 2 == 0 { 1e300 } else { -1e300 },
        ),
        ("dynamic-range", |i| 10f64.powi((i % 600) as i32 - 300)),
        ("mostly-nan", |i| if i % 7 == 0 { 1.0 } else { f64::NAN }),
    ];

    fn poison(res: &mut Results, f: Series) {
        for e in &mut res.estimators {
            for v in &mut e.values {
                for (i, x) in v.iter_mut().enumerate() {
                    *x = f(i);
                }
            }
        }
    }

    fn poison_sweep(sw: &mut SweepResults, f: Series) {
        poison(&mut sw.base, f);
        for p in &mut sw.points {
            poison(&mut p.results, f);
        }
        for (i, row) in sw.summary.iter_mut().enumerate() {
            row.mean = f(i);
            row.std = f(i + 1);
        }
    }

    fn tiny(sc: Scenario) -> Scenario {
        sc.with_size(Some(2), Some(120), Some(10))
            .expect("tiny size")
    }

    #[test]
    fn garkf_figures_survive_pathological_data_in_bounded_time() {
        let dir = std::env::temp_dir().join(format!("edgekf-garkf-patho-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let limit = Duration::from_secs(20);
        let mut drawn = 0;
        for name in [
            "garkf-fig8",
            "garkf-fig9",
            "garkf-fig10",
            "garkf-fig11",
            "garkf-fig12",
            "garkf-fig13",
        ] {
            let e = reproductions::find(name).unwrap();
            let sc = tiny(e.scenario().unwrap());
            let companions: Vec<Scenario> = e
                .companion_scenarios()
                .unwrap()
                .into_iter()
                .map(tiny)
                .collect();
            let clean = sim::sweep::run(&sc, &Quiet).unwrap();
            let clean_companions: Vec<SweepResults> = companions
                .iter()
                .map(|c| sim::sweep::run(c, &Quiet).unwrap())
                .collect();
            for (sname, f) in SERIES {
                let mut sw = clean.clone();
                poison_sweep(&mut sw, *f);
                let mut comp = clean_companions.clone();
                for c in &mut comp {
                    poison_sweep(c, *f);
                }
                let extra = Extra {
                    sweep: sc.sweep().is_some().then_some(&sw),
                    companions: companions.iter().zip(&comp).collect(),
                };
                for p in sc.plots().iter().filter(|p| handles(p)) {
                    let path = dir.join(format!("{name}-{}-{sname}.png", p.file()));
                    let t = Instant::now();
                    let out = render(&path, p, &sc, &sw.base, &extra);
                    assert!(
                        t.elapsed() < limit,
                        "{name} {} on `{sname}` took {:?}",
                        p.file(),
                        t.elapsed()
                    );
                    assert!(
                        out.is_ok(),
                        "{name} {} on `{sname}` is not drawn: {:?}",
                        p.file(),
                        out.err()
                    );
                    assert!(path.exists(), "{}", path.display());
                    drawn += 1;
                }
            }
        }
        // fig8, fig10, fig12 panels; fig9 indicator; fig11 panels + summary; fig13 summary.
        assert_eq!(drawn, 7 * SERIES.len());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
