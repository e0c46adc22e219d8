//! Renders a gallery of typical figures with the figure toolkit, from synthetic data shaped like the papers':
//!
//! ```sh
//! cargo run -p edgekf-cli --example figure_gallery -- target/figure-gallery
//! ```
//!
//! writes `metric_log.png` (ε with ±1σ bands, log y, log time), `metric_inset.png` (the same on the papers'
//! linear 0–30 s axis with an inset over the first second), `coincide.png` (five curves equal within 0.1 %),
//! `coincide_difference.png` (the same with a panel of their differences), `paths.png` (ten agents, final
//! links, start/end markers), `design.png` (a framework: weights labelled above the links), `inputs.png`
//! (3,000 noisy points, two panels), `pathological.png` (NaN, ±inf, 1e300, zeros on a log axis), `text.png`
//! (symbols and kerning) and `kerning.png` (plotters' text above the toolkit's, 3× enlarged), and prints each
//! figure's warnings.

use std::path::PathBuf;

use edgekf_figure::{
    palette, Axis, Canvas, Curve, Dash, Figure, HAlign, Inset, Label, Marker, Panel, Rgb, Shape,
    Style, VAlign,
};
use plotters::prelude::*;

/// A small deterministic generator (xorshift64*), so the gallery is the same on every machine.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A standard normal draw (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// ε-like curves: a transient from 1 to a steady level, noisy mean over 50 runs, and its ±1σ band.
fn error_curves(t: &[f64], noise: &mut Noise) -> Vec<Curve> {
    let names = ["none", "mle", "rkf", "jrkf", "crkf"];
    let steady = [1.1, 0.35, 0.058, 0.055, 0.035];
    let rate = [0.0, 0.0, 6.0, 7.0, 9.0];
    names
        .iter()
        .enumerate()
        .map(|(k, n)| {
            let mean: Vec<f64> = t
                .iter()
                .map(|&t| {
                    let m = steady[k]
                        + if rate[k] > 0.0 {
                            0.35 * (-rate[k] * t).exp()
                        } else {
                            0.0
                        };
                    m * (1.0 + 0.04 * noise.normal())
                })
                .collect();
            let lower: Vec<f64> = mean.iter().map(|m| m * 0.45).collect();
            let upper: Vec<f64> = mean.iter().map(|m| m * 1.55).collect();
            let label = if *n == "none" {
                "none (raw measurement)".to_string()
            } else {
                (*n).to_string()
            };
            Curve::new(label, t.to_vec(), mean).with_band(lower, upper)
        })
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/figure-gallery".into()),
    );
    std::fs::create_dir_all(&dir)?;
    let mut noise = Noise(0x9E37_79B9_7F4A_7C15);
    let t: Vec<f64> = (1..=3000).map(|k| f64::from(k) * 0.01).collect();
    let mut figures: Vec<(&str, Figure)> = Vec::new();

    // 1. Estimation error, log y and log time: the transient is visible.
    let mut p = Panel::new(
        Axis::log("time t", "s").tight(),
        Axis::log("estimation error ε_{k} = ‖x_{k} − x̂_{k|k}‖", "m"),
    );
    p.curves = error_curves(&t, &mut noise);
    figures.push((
        "metric_log",
        Figure::single("Estimation error, mean ± 1σ over 50 runs", p),
    ));

    // 2. The papers' linear time axis with an inset over the first second.
    let mut p = Panel::new(
        Axis::linear("time t", "s").tight(),
        Axis::log("estimation error ε_{k}", "m"),
    )
    .with_inset(Inset::new(0.0, 1.0, "first second"));
    p.curves = error_curves(&t, &mut noise);
    figures.push((
        "metric_inset",
        Figure::single(
            "Estimation error on a linear time axis, with the transient inset",
            p,
        ),
    ));

    // 3. Five curves that coincide, plus a baseline that does not.
    let mut p = Panel::new(
        Axis::linear("time t", "s").tight(),
        Axis::log("Procrustes error", "m"),
    );
    for (k, pf) in ["0", "0.25", "0.5", "0.75", "1"].iter().enumerate() {
        let y: Vec<f64> = t
            .iter()
            .map(|&t| (2e-3 + 0.5 * (-0.45 * t).exp()) * (1.0 + 1e-4 * k as f64))
            .collect();
        p.curves.push(Curve::new(
            format!("rkf-ar P_{{fail}} = {pf}"),
            t.clone(),
            y,
        ));
    }
    let y: Vec<f64> = t.iter().map(|&t| 6e-3 + 0.5 * (-0.4 * t).exp()).collect();
    p.curves.push(
        Curve::new("û = 0 baseline (no input prediction)", t.clone(), y)
            .with_style(Style::line().dashed()),
    );
    figures.push((
        "coincide",
        Figure::single("Random link failures: Procrustes error", p.clone()),
    ));
    // The same with a panel of the differences that the legend summarises as "coincide within 0.1 %".
    let groups = p.coinciding();
    let diff = p
        .difference_panel(&groups[0])
        .with_title("differences within the group");
    let mut f = Figure::new("Random link failures, with the coinciding curves' differences")
        .with_size(1100, 1000);
    f.panels = vec![p, diff];
    figures.push(("coincide_difference", f));

    // 4. Paths: ten agents converge to a formation; final links grey, starts hollow, ends filled.
    let n = 10;
    let target: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            (2.0 * a.cos(), 1.5 * a.sin())
        })
        .collect();
    let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"));
    p.equal_aspect = true;
    let steps = 400;
    let mut ends = Vec::new();
    let mut paths = Vec::new();
    for (i, &(tx, ty)) in target.iter().enumerate() {
        let (mut x, mut y) = (3.0 * noise.normal(), 3.0 * noise.normal());
        let (mut xs, mut ys) = (vec![x], vec![y]);
        for _ in 0..steps {
            x += 0.02 * (tx - x) + 0.01 * noise.normal();
            y += 0.02 * (ty - y) + 0.01 * noise.normal();
            xs.push(x);
            ys.push(y);
        }
        ends.push((x, y));
        let (colour, dash) = palette::agent(i);
        paths.push(
            Curve::new(format!("agent {i}"), xs, ys)
                .with_style(Style::line().colour(colour).dash(dash)),
        );
    }
    for i in 0..n as usize {
        for j in [(i + 1) % n as usize, (i + 3) % n as usize] {
            let (a, b) = (ends[i], ends[j]);
            p.curves.push(
                Curve::new("final links", vec![a.0, b.0], vec![a.1, b.1])
                    .with_style(Style::line().colour(palette::LINK).width(1.2)),
            );
        }
    }
    let starts: (Vec<f64>, Vec<f64>) = paths.iter().map(|c| (c.x[0], c.y[0])).unzip();
    p.curves.extend(paths);
    p.curves
        .push(Curve::new("start", starts.0, starts.1).with_style(
            Style::markers(Marker::new(Shape::Circle, 8.0).hollow()).colour(palette::MARKER),
        ));
    let fin: (Vec<f64>, Vec<f64>) = ends.iter().copied().unzip();
    p.curves.push(
        Curve::new("end", fin.0, fin.1).with_style(
            Style::markers(Marker::new(Shape::TriangleUp, 10.0)).colour(palette::MARKER),
        ),
    );
    p.curves.push(
        Curve::new(
            "leaders (end)",
            vec![ends[0].0, ends[1].0],
            vec![ends[0].1, ends[1].1],
        )
        .with_style(Style::markers(Marker::new(Shape::TriangleUp, 10.0)).colour(palette::LEADER)),
    );
    for (i, &(x, y)) in ends.iter().enumerate() {
        p.labels.push(Label::new(x, y, format!("{i}")));
    }
    figures.push((
        "paths",
        Figure::single("Agent paths, run 0, 0–4 s", p).with_size(900, 860),
    ));

    // 4b. A framework picture: link width by weight, weight labels above the links, units on the axes.
    let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"));
    p.equal_aspect = true;
    let hex: Vec<(f64, f64)> = (0..6)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / 6.0;
            (a.cos(), a.sin())
        })
        .collect();
    for i in 0..6usize {
        for j in [(i + 1) % 6, (i + 2) % 6] {
            let w: f64 = if j == (i + 1) % 6 { 0.8 } else { -0.3 };
            let (a, b) = (hex[i], hex[j]);
            let (colour, label) = if w > 0.0 {
                (palette::SERIES[0], "positive weight (width ∝ |w|)")
            } else {
                (palette::SERIES[1], "negative weight")
            };
            p.curves.push(
                Curve::new(label, vec![a.0, b.0], vec![a.1, b.1])
                    .with_style(Style::line().colour(colour).width(1.0 + 5.0 * w.abs())),
            );
            p.labels.push(Label {
                size: 13.0,
                ..Label::new(
                    (a.0 + b.0) / 2.0,
                    (a.1 + b.1) / 2.0,
                    format!("{w:+.1}").replace('-', "−"),
                )
            });
        }
    }
    let (ax, ay): (Vec<f64>, Vec<f64>) = hex.iter().copied().unzip();
    p.curves.push(
        Curve::new("agents", ax, ay)
            .with_style(Style::markers(Marker::new(Shape::Circle, 14.0)).colour(palette::MARKER)),
    );
    for (i, &(x, y)) in hex.iter().enumerate() {
        p.labels.push(Label {
            offset: (9.0, -9.0),
            h: HAlign::Left,
            ..Label::new(x, y, format!("{i}"))
        });
    }
    figures.push((
        "design",
        Figure::single("A hexagon framework: stress weights w_{ij}", p).with_size(800, 780),
    ));

    // 5. Control inputs: 3,000 noisy points per curve, two panels.
    let ux: Vec<f64> = t
        .iter()
        .map(|&t| 3.0 * (-2.0 * t).exp() * (5.0 * t).cos() + 0.02 * noise.normal())
        .collect();
    let uy: Vec<f64> = t
        .iter()
        .map(|&t| -2.0 * (-2.0 * t).exp() + 0.02 * noise.normal())
        .collect();
    let whole = Panel::new(
        Axis::linear("time t", "s").tight(),
        Axis::linear("control input u", "m/s"),
    )
    .with_title("whole run")
    .with_curve(Curve::new("u_{x}", t.clone(), ux.clone()).with_style(Style::line().width(1.0)))
    .with_curve(Curve::new("u_{y}", t.clone(), uy.clone()).with_style(Style::line().width(1.0)));
    let from = 500;
    let steady = Panel::new(
        Axis::linear("time t", "s").tight(),
        Axis::linear("control input u", "m/s"),
    )
    .with_title("steady state (5–30 s)")
    .with_curve(
        Curve::new("u_{x}", t[from..].to_vec(), ux[from..].to_vec())
            .with_style(Style::line().width(1.0)),
    )
    .with_curve(
        Curve::new("u_{y}", t[from..].to_vec(), uy[from..].to_vec())
            .with_style(Style::line().width(1.0)),
    );
    let mut f = Figure::new("Control input of agent 0 (rkf, run 0)").with_size(1100, 900);
    f.panels = vec![whole, steady];
    figures.push(("inputs", f));

    // 6. Pathological data: everything is drawn, nothing hangs, the notes say what was left out.
    let mut y: Vec<f64> = t.iter().map(|&t| (-t).exp()).collect();
    y[10] = f64::NAN;
    y[20] = f64::INFINITY;
    y[30] = 0.0;
    y[40] = -1.0;
    y[50] = 1e300;
    let p = Panel::new(Axis::linear("time t", "s").tight(), Axis::log("value", ""))
        .with_curve(Curve::new("mixed", t.clone(), y))
        .with_curve(
            Curve::new("constant", t.clone(), vec![0.5; t.len()])
                .with_style(Style::line().dash(Dash::DashDot)),
        );
    figures.push(("pathological", Figure::single("Pathological data", p)));

    // 7. Text: symbols and kerning.
    let mut p = Panel::new(
        Axis::linear("time t", "s"),
        Axis::linear("formation error ‖p_{i} − p_{j}‖", "m"),
    );
    for (k, s) in [
        "landmarks, time t (s), formation, immersion",
        "x̂_{k|k}, ε_{k}², σ^{2}_{prior} = 10⁻⁵, λ_{max}, ‖·‖, Ŵ, Â",
        "P_{fail} ∈ {0, 0.25, 0.5}, û = 0 (no input prediction)",
    ]
    .iter()
    .enumerate()
    {
        p.labels.push(Label {
            size: 22.0,
            ..Label::new(0.5, 2.5 - k as f64, *s)
        });
    }
    p.curves.push(
        Curve::new("", vec![0.0, 1.0], vec![0.0, 3.0])
            .with_style(Style::line().colour(Rgb(200, 200, 200))),
    );
    figures.push((
        "text",
        Figure::single("Typesetting: landmarks, time, formation", p),
    ));

    kerning_before_after(&dir)?;
    for (name, fig) in &figures {
        let path = dir.join(format!("{name}.png"));
        let rep = fig.render(&path)?;
        println!("{}", path.display());
        for w in rep.warnings() {
            println!("  {w}");
        }
        for p in &rep.panels {
            if let Some(l) = &p.legend {
                println!("  legend: {:?} (covers {})", l.placement, l.covered);
            }
            for g in &p.coinciding {
                println!(
                    "  coincide: {:?} (max deviation {:.1e})",
                    g.labels, g.max_deviation
                );
            }
        }
    }
    Ok(())
}

/// `kerning.png`: the same words by plotters' ab_glyph text (top) and by the toolkit (bottom), 3× enlarged.
fn kerning_before_after(dir: &std::path::Path) -> Result<(), Box<dyn std::error::Error>> {
    let words = "landmarks, time t (s), formation, x̂_k|k";
    let (w, h) = (330u32, 110u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            edgekf_figure::text::font_bytes(),
        );
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        for (k, size) in [15, 16, 17].iter().enumerate() {
            root.draw(&Text::new(
                words,
                (4, 4 + 34 * k as i32),
                ("sans-serif", *size).into_font(),
            ))?;
        }
        root.present()?;
    }
    let before = Canvas::from_rgb(w, h, buf).ok_or("buffer size")?;
    let mut after = Canvas::new(w, h);
    for (k, size) in [15.0, 16.0, 17.0].iter().enumerate() {
        after.draw_text(
            words,
            *size,
            (4.0, 4.0 + 34.0 * k as f64),
            HAlign::Left,
            VAlign::Top,
            Rgb::BLACK,
        );
    }
    let mut both = Canvas::new(w, 2 * h + 4);
    both.paste(&before, 0, 0);
    both.paste(&after, 0, h as i32 + 4);
    let path = dir.join("kerning.png");
    both.zoomed(3).save_png(&path)?;
    println!(
        "{} (top: plotters' text; bottom: the toolkit's)",
        path.display()
    );
    Ok(())
}
