//! No hang, no panic, whatever the data (issue 16, point 1): every plot kind of the figure toolkit is drawn on
//! pathological series, each case in its own thread with a time limit.
//!
//! plotters' own key-point computation spins forever on some huge ranges (`compute_f64_key_points`, e.g. an
//! axis over 0..1e300) and panics on others (`coord/ranged1d/types/numeric.rs:243`); the toolkit never lets
//! plotters compute key points, and these cases would hang or panic if it did.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use edgekf_figure::{
    Axis, Curve, Dash, Figure, Inset, Label, LegendMode, Marker, Panel, Rgb, Shade, Shape, Style,
};

/// Per-case limit. A render takes milliseconds; ten seconds only trips on a hang.
const LIMIT: Duration = Duration::from_secs(10);

/// Named (x, y) series.
fn series() -> Vec<(&'static str, Vec<f64>, Vec<f64>)> {
    let t = |n: usize| -> Vec<f64> { (0..n).map(|k| k as f64 * 0.01).collect() };
    let n = 300;
    let mut v = vec![
        ("1e300", t(n), vec![1e300; n]),
        ("-1e300", t(n), vec![-1e300; n]),
        ("1e-300", t(n), vec![1e-300; n]),
        (
            "0..1e300",
            t(n),
            (0..n).map(|k| k as f64 * 1e300 / n as f64).collect(),
        ),
        (
            "1e-300..1e300",
            t(n),
            (0..n)
                .map(|k| 10f64.powf(-300.0 + 600.0 * k as f64 / n as f64))
                .collect(),
        ),
        (
            "±MAX",
            t(n),
            (0..n)
                .map(|k| if k % 2 == 0 { f64::MAX } else { -f64::MAX })
                .collect(),
        ),
        ("subnormal", t(n), vec![5e-324; n]),
        ("constant", t(n), vec![0.7; n]),
        ("zeros", t(n), vec![0.0; n]),
        ("negative", t(n), (0..n).map(|k| -1.0 - k as f64).collect()),
        ("all NaN", t(n), vec![f64::NAN; n]),
        (
            "NaN mixed",
            t(n),
            (0..n)
                .map(|k| {
                    if k % 7 == 0 {
                        f64::NAN
                    } else {
                        (k as f64).sin()
                    }
                })
                .collect(),
        ),
        (
            "±inf",
            t(n),
            (0..n)
                .map(|k| match k % 3 {
                    0 => f64::INFINITY,
                    1 => f64::NEG_INFINITY,
                    _ => k as f64,
                })
                .collect(),
        ),
        ("empty", Vec::new(), Vec::new()),
        ("single point", vec![1.0], vec![2.0]),
        (
            "x all NaN",
            vec![f64::NAN; n],
            (0..n).map(|k| k as f64).collect(),
        ),
        (
            "x constant",
            vec![3.0; n],
            (0..n).map(|k| k as f64).collect(),
        ),
        (
            "x huge",
            (0..n).map(|k| k as f64 * 1e298).collect(),
            (0..n).map(|k| k as f64).collect(),
        ),
        (
            "x unsorted",
            (0..n).map(|k| ((k * 37) % n) as f64).collect(),
            (0..n).map(|k| k as f64).collect(),
        ),
        ("lengths differ", t(n), vec![1.0; 10]),
        (
            "tiny relative width",
            t(n),
            (0..n).map(|k| 1e15 + (k % 2) as f64 * 0.1).collect(),
        ),
    ];
    let big: usize = 1_000_000;
    v.push((
        "10^6 points",
        (0..big).map(|k| k as f64 * 1e-3).collect(),
        (0..big)
            .map(|k| 1.0 + ((k * 7919) % 1000) as f64 * 1e-3)
            .collect(),
    ));
    v
}

/// Builds a figure of one kind from an (x, y) series.
type Kind = fn(Vec<f64>, Vec<f64>) -> Figure;

/// The plot kinds: every feature a figure of the project uses.
fn kinds() -> Vec<(&'static str, Kind)> {
    fn lin(x: Vec<f64>, y: Vec<f64>) -> Figure {
        Figure::single(
            "linear",
            Panel::new(Axis::linear("t", "s"), Axis::linear("y", "m"))
                .with_curve(Curve::new("a", x, y)),
        )
    }
    fn log_y_band(x: Vec<f64>, y: Vec<f64>) -> Figure {
        let lo: Vec<f64> = y.iter().map(|v| v - 0.5 * v.abs()).collect();
        let hi: Vec<f64> = y.iter().map(|v| v * 2.0).collect();
        Figure::single(
            "log y with band",
            Panel::new(Axis::linear("t", "s").tight(), Axis::log("ε_{k}", "m"))
                .with_curve(Curve::new("mean ± 1σ", x, y).with_band(lo, hi)),
        )
    }
    fn log_log(x: Vec<f64>, y: Vec<f64>) -> Figure {
        Figure::single(
            "log-log",
            Panel::new(Axis::log("t", "s"), Axis::log("y", "m"))
                .with_curve(Curve::new("a", x.clone(), y.clone()))
                .with_curve(Curve::new("b", x, y).with_style(Style::line().dash(Dash::Dotted))),
        )
    }
    fn coincide(x: Vec<f64>, y: Vec<f64>) -> Figure {
        let mut p = Panel::new(Axis::linear("t", "s"), Axis::log("y", ""));
        for k in 0..4 {
            p.curves.push(Curve::new(
                format!("P_{{fail}} = {k}"),
                x.clone(),
                y.clone(),
            ));
        }
        Figure::single("coinciding curves", p)
    }
    fn paths(x: Vec<f64>, y: Vec<f64>) -> Figure {
        let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"));
        p.equal_aspect = true;
        p.labels.push(Label::new(
            x.first().copied().unwrap_or(0.0),
            y.first().copied().unwrap_or(0.0),
            "m_{0}",
        ));
        p.curves.push(Curve::new("path", y.clone(), x.clone()));
        p.curves.push(
            Curve::new("ends", x, y)
                .with_style(Style::markers(Marker::new(Shape::Diamond, 9.0)).colour(Rgb::BLACK)),
        );
        Figure::single("paths", p).with_size(700, 700)
    }
    fn inset(x: Vec<f64>, y: Vec<f64>) -> Figure {
        let mut p = Panel::new(Axis::linear("t", "s"), Axis::log("y", "m"))
            .with_curve(Curve::new("a", x, y))
            .with_inset(Inset::new(0.0, 0.5, "first 0.5 s"));
        p.shades.push(Shade {
            from: 0.2,
            to: 0.4,
            label: "window".into(),
            colour: Rgb(230, 230, 230),
        });
        Figure::single("inset", p)
    }
    fn panels(x: Vec<f64>, y: Vec<f64>) -> Figure {
        let a = Panel::new(Axis::linear("t", "s"), Axis::linear("u", "m/s"))
            .with_title("whole run")
            .with_curve(
                Curve::new("u_{x}", x.clone(), y.clone()).with_style(Style::line().width(1.0)),
            );
        let mut b = Panel::new(Axis::log("t", "s"), Axis::linear("u", "m/s"))
            .with_title("log time")
            .with_curve(Curve::new("u_{x}", x, y));
        b.legend = LegendMode::Outside;
        let mut f = Figure::new("two panels").with_size(900, 800);
        f.panels = vec![a, b];
        f
    }
    fn tiny(x: Vec<f64>, y: Vec<f64>) -> Figure {
        Figure::single(
            "a very small figure with a very long title that cannot fit",
            Panel::new(Axis::log("t", "s"), Axis::log("y", "m")).with_curve(Curve::new("a", x, y)),
        )
        .with_size(60, 40)
    }
    vec![
        ("linear", lin),
        ("log y + band", log_y_band),
        ("log-log", log_log),
        ("coinciding", coincide),
        ("paths", paths),
        ("inset + shade", inset),
        ("two panels", panels),
        ("tiny", tiny),
    ]
}

#[test]
fn every_plot_kind_survives_pathological_data_in_bounded_time() {
    let mut failures = Vec::new();
    let mut slowest = (Duration::ZERO, String::new());
    for (sname, x, y) in series() {
        for (kname, kind) in kinds() {
            // The 10^6 case once per kind is enough, but every kind gets it.
            let (x, y) = (x.clone(), y.clone());
            let (tx, rx) = mpsc::channel();
            let case = format!("{kname} × {sname}");
            let started = Instant::now();
            let handle = std::thread::spawn(move || {
                let fig = kind(x, y);
                let (canvas, report) = fig.draw();
                let _ = tx.send((canvas.width(), report));
            });
            match rx.recv_timeout(LIMIT) {
                Ok((w, report)) => {
                    assert!(w > 0);
                    // Every axis range is finite and ordered, every tick finite.
                    for p in &report.panels {
                        for a in [&p.x, &p.y] {
                            assert!(
                                a.lo.is_finite() && a.hi.is_finite() && a.lo < a.hi,
                                "{case}: {a:?}"
                            );
                        }
                        assert!(
                            p.x_ticks
                                .iter()
                                .chain(&p.y_ticks)
                                .all(|t| t.value.is_finite()),
                            "{case}"
                        );
                    }
                    let _ = handle.join();
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    failures.push(format!("{case}: no result within {LIMIT:?} (hang)"));
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let msg = match handle.join() {
                        Err(p) => p
                            .downcast_ref::<String>()
                            .cloned()
                            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_default(),
                        Ok(()) => String::new(),
                    };
                    failures.push(format!("{case}: panicked: {msg}"));
                }
            }
            let took = started.elapsed();
            if std::env::var_os("FIGURE_TIMES").is_some() {
                eprintln!("{took:>10.3?}  {case}");
            }
            if took > slowest.0 {
                slowest = (took, case);
            }
        }
    }
    eprintln!("slowest case: {} ({:?})", slowest.1, slowest.0);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn left_out_values_are_counted_and_said() {
    let x: Vec<f64> = (0..100).map(f64::from).collect();
    let mut y: Vec<f64> = x.iter().map(|v| v + 1.0).collect();
    y[3] = f64::NAN;
    y[4] = f64::INFINITY;
    y[5] = 0.0;
    y[6] = -2.0;
    let fig = Figure::single(
        "counts",
        Panel::new(Axis::linear("t", "s"), Axis::log("y", "m")).with_curve(Curve::new("a", x, y)),
    );
    let (_, rep) = fig.draw();
    let c = &rep.panels[0].curves[0];
    assert_eq!((c.points, c.non_finite, c.non_positive), (100, 2, 2));
    let w = rep.warnings();
    assert!(
        w.iter()
            .any(|s| s.starts_with("2 non-finite values left out")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|s| s.starts_with("2 values ≤ 0 left out of the log axis")),
        "{w:?}"
    );
    assert_eq!(
        rep.problems().len(),
        1,
        "only the non-finite values are a problem"
    );
}

#[test]
fn exact_zeros_do_not_stretch_a_log_axis() {
    // An error that is exactly zero until a disturbance, then rises and decays (the SLAM figure).
    let t: Vec<f64> = (0..1000).map(|k| f64::from(k) * 0.01).collect();
    let e: Vec<f64> = t
        .iter()
        .map(|&t| {
            if t < 1.0 {
                0.0
            } else {
                0.3 * (-(t - 1.0)).exp()
            }
        })
        .collect();
    let fig = Figure::single(
        "zeros",
        Panel::new(Axis::linear("t", "s").tight(), Axis::log("error", "m"))
            .with_curve(Curve::new("e", t, e)),
    );
    let (_, rep) = fig.draw();
    let p = &rep.panels[0];
    assert!(p.y.lo > 1e-5, "log axis starts at {}", p.y.lo);
    assert_eq!(p.curves[0].non_positive, 100);
    // The time axis still shows the whole run.
    assert!(p.x.lo <= 0.0);
}

#[test]
fn round_off_sized_values_do_not_take_the_axis() {
    let t: Vec<f64> = (0..1000).map(|k| f64::from(k) * 0.01).collect();
    let e: Vec<f64> = t
        .iter()
        .map(|&t| {
            if t < 3.0 {
                1e-16 * (1.0 + t)
            } else {
                0.3 * (-(t - 3.0)).exp()
            }
        })
        .collect();
    let fig = Figure::single(
        "round-off",
        Panel::new(Axis::linear("t", "s").tight(), Axis::log("error", "m"))
            .with_curve(Curve::new("e", t, e)),
    );
    let (_, rep) = fig.draw();
    let y = &rep.panels[0].y;
    // The floor, less the 3 % margin of the axis.
    assert!(y.lo >= 1e-13 && y.floor.is_some(), "{y:?}");
    assert_eq!(y.below_floor, 300);
    assert!(rep
        .warnings()
        .iter()
        .any(|w| w.contains("at most 12 decades below its largest value")));
}

#[test]
fn writes_a_png() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("figure-png");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("one.png");
    let fig = Figure::single(
        "one",
        Panel::new(Axis::linear("t", "s"), Axis::linear("y", "m")).with_curve(Curve::new(
            "a",
            vec![0.0, 1.0],
            vec![1.0, 2.0],
        )),
    );
    fig.render(&path).expect("written");
    let bytes = std::fs::read(&path).expect("readable");
    assert_eq!(&bytes[1..4], b"PNG");
}
