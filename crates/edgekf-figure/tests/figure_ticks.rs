//! Tick labels as drawn: powers of ten with superscripts, no `e` notation, no `−0`, and no label overlapping
//! another or leaving the image, for ordinary and pathological ranges.

use edgekf_figure::{Axis, Curve, Figure, Panel, Scale};

fn labels_ok(name: &str, fig: &Figure) {
    let (canvas, rep) = fig.draw();
    let (w, h) = (f64::from(canvas.width()), f64::from(canvas.height()));
    for p in &rep.panels {
        for (s, r) in &p.texts {
            assert!(
                r.x0 >= 0.0 && r.y0 >= 0.0 && r.x1 <= w && r.y1 <= h,
                "{name}: {s:?} at {r:?} leaves the {w}×{h} image"
            );
        }
        for (i, (a, ra)) in p.texts.iter().enumerate() {
            for (b, rb) in &p.texts[..i] {
                assert!(
                    !ra.intersects(rb),
                    "{name}: {a:?} {ra:?} overlaps {b:?} {rb:?}"
                );
            }
        }
        for (t, scale) in p
            .x_ticks
            .iter()
            .map(|t| (t, p.x_scale))
            .chain(p.y_ticks.iter().map(|t| (t, p.y_scale)))
        {
            let Some(l) = &t.label else { continue };
            assert!(!l.contains('e') && !l.contains('E'), "{name}: {l:?}");
            assert!(!l.contains('-'), "{name}: ASCII hyphen in {l:?}");
            assert!(
                l.trim_start_matches('−')
                    .chars()
                    .any(|c| c != '0' && c != '.')
                    || !l.starts_with('−'),
                "{name}: negative zero {l:?}"
            );
            if scale == Scale::Log {
                assert!(l.contains("10") || l == "0", "{name}: log label {l:?}");
            }
        }
    }
}

fn line(x: Axis, y: Axis, xs: Vec<f64>, ys: Vec<f64>) -> Figure {
    Figure::single(
        "ticks",
        Panel::new(x, y).with_curve(Curve::new("a", xs, ys)),
    )
}

#[test]
fn labels_are_typeset_and_fit_the_image() {
    let t: Vec<f64> = (0..=300).map(|k| f64::from(k) * 0.1).collect();
    let cases: Vec<(&str, Figure)> = vec![
        (
            "time 0–30 s, tight (the 30.0 at the edge)",
            line(
                Axis::linear("t", "s").tight(),
                Axis::linear("u", "m/s"),
                t.clone(),
                t.iter().map(|v| (v * 0.7).sin() * 0.3).collect(),
            ),
        ),
        (
            "around zero",
            line(
                Axis::linear("t", "s"),
                Axis::linear("u", "m/s"),
                t.clone(),
                t.iter().map(|v| -0.35 + v * 0.029).collect(),
            ),
        ),
        (
            "log decades",
            line(
                Axis::log("t", "s"),
                Axis::log("ε", "m"),
                t[1..].to_vec(),
                t[1..].iter().map(|v| 1e-3 / v).collect(),
            ),
        ),
        (
            "narrow log",
            line(
                Axis::linear("t", "s"),
                Axis::log("ε", "m"),
                t.clone(),
                t.iter().map(|v| 0.015 + v * 0.0015).collect(),
            ),
        ),
        (
            "600 decades",
            line(
                Axis::linear("t", "s"),
                Axis::log("y", ""),
                t.clone(),
                t.iter().map(|v| 10f64.powf(-300.0 + v * 20.0)).collect(),
            ),
        ),
        (
            "0..1e300",
            line(
                Axis::linear("t", "s"),
                Axis::linear("y", ""),
                t.clone(),
                t.iter().map(|v| v * 3.3e298).collect(),
            ),
        ),
        (
            "±1e300",
            line(
                Axis::linear("x", ""),
                Axis::linear("y", ""),
                t.iter().map(|v| (v - 15.0) * 6e298).collect(),
                t.clone(),
            ),
        ),
        (
            "1e15 + tiny",
            line(
                Axis::linear("t", "s"),
                Axis::linear("y", ""),
                t.clone(),
                t.iter().map(|v| 1e15 + v * 1e-3).collect(),
            ),
        ),
        (
            "large linear",
            line(
                Axis::linear("t", "s"),
                Axis::linear("y", ""),
                t.clone(),
                t.iter().map(|v| v * 123_456.0).collect(),
            ),
        ),
        (
            "small figure",
            line(
                Axis::linear("t", "s"),
                Axis::log("ε", "m"),
                t.clone(),
                t.iter().map(|v| 1.0 + v).collect(),
            )
            .with_size(320, 240),
        ),
    ];
    for (name, fig) in &cases {
        labels_ok(name, fig);
    }
}

#[test]
fn a_narrow_log_axis_gets_mantissa_labels() {
    let t: Vec<f64> = (0..=100).map(f64::from).collect();
    let fig = line(
        Axis::linear("t", "s"),
        Axis::log("ε", "m").with_range(1.5e-2, 6e-2),
        t.clone(),
        t.iter().map(|v| 0.02 + v * 3e-4).collect(),
    );
    let (_, rep) = fig.draw();
    let labels: Vec<&str> = rep.panels[0]
        .y_ticks
        .iter()
        .filter_map(|t| t.label.as_deref())
        .collect();
    assert!((2..=5).contains(&labels.len()), "{labels:?}");
    assert!(labels.contains(&"2·10⁻²"), "{labels:?}");
}

#[test]
fn log_time_axis_labels_decades() {
    let t: Vec<f64> = (1..=30000).map(|k| f64::from(k) * 1e-3).collect();
    let fig = line(
        Axis::log("time t", "s").tight(),
        Axis::log("ε", "m"),
        t.clone(),
        t.iter().map(|v| 0.05 + (-5.0 * v).exp()).collect(),
    );
    let (_, rep) = fig.draw();
    let labels: Vec<&str> = rep.panels[0]
        .x_ticks
        .iter()
        .filter_map(|t| t.label.as_deref())
        .collect();
    assert_eq!(
        labels,
        ["10⁻³", "10⁻²", "10⁻¹", "10⁰", "10¹"],
        "{:?}",
        rep.panels[0].x
    );
}

/// A noisy ±1σ band on a log axis (σ about the mean: lower edges tiny or ≤ 0) does not stretch
/// the axis: it spans at most a decade below the lowest curve value (plus the margin), and the
/// band values left out are counted.
#[test]
fn log_axis_is_not_stretched_by_a_bands_lower_edge() {
    let t: Vec<f64> = (1..=400).map(|k| f64::from(k) * 0.1).collect();
    let mean: Vec<f64> = t.iter().map(|t| 1e-2 * (1.5 + (3.0 * t).sin())).collect();
    // σ alternates just below and above the mean: lower edges 1e-7 … 1e-3 of the mean, or < 0.
    let sd: Vec<f64> = mean
        .iter()
        .enumerate()
        .map(|(k, m)| {
            m * if k % 2 == 0 {
                1.0 - 10f64.powi(-(k as i32 % 7))
            } else {
                1.3
            }
        })
        .collect();
    let lo: Vec<f64> = mean.iter().zip(&sd).map(|(m, s)| m - s).collect();
    let hi: Vec<f64> = mean.iter().zip(&sd).map(|(m, s)| m + s).collect();
    let panel = Panel::new(Axis::linear("time t", "s"), Axis::log("tr Λ", "m²"))
        .with_curve(Curve::new("garkf", t, mean.clone()).with_band(lo, hi));
    let (_, rep) = Figure::single("band", panel).draw();
    let p = &rep.panels[0];
    let lowest = mean.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(
        p.y.lo >= lowest / 10.0 / 2.0,
        "axis from {} for a lowest mean {lowest}",
        p.y.lo
    );
    assert!(p.curves[0].band_outside > 100, "{:?}", p.curves[0]);
}
