//! Figures for the SLAM observer, drawn with the figure toolkit (`crate::figure`): a Fig. 3-style map of paths
//! and landmark estimates, and error curves on a log axis.

use anyhow::Result;
use edgekf_slam::{Scenario, Trajectory};
use std::path::Path;

use crate::figure::{
    palette, Axis, Curve, Dash, Figure, HAlign, Label, Marker, Panel, Rgb, Shade, Shape, Style,
    VAlign,
};

/// Colour of all robot paths (Okabe–Ito bluish green, as the paper's green paths).
const PATH: Rgb = palette::SERIES[2];

/// Colour of robot i's estimate tracks and error curve: the Okabe–Ito colours other than the paths' green and
/// the markers' black.
fn robot_colour(i: usize) -> Rgb {
    const C: [Rgb; 5] = [
        palette::SERIES[0],
        palette::SERIES[1],
        palette::SERIES[3],
        palette::SERIES[4],
        palette::SERIES[5],
    ];
    C[i % C.len()]
}

/// Writes the abnormal findings of a render (non-finite values, clamped ranges) to stderr; the figure itself
/// carries the same as a note.
fn warn(path: &Path, rep: &crate::figure::RenderReport) {
    for w in rep.problems() {
        eprintln!("warning: {}: {w}", path.display());
    }
}

/// Fig. 3 of the paper: robot paths (green), initial positions (hollow circles), final positions (black
/// diamonds), each robot's estimated landmark tracks dashed in its own colour, true landmarks as black crosses.
pub fn paths(path: &Path, sc: &Scenario, tr: &Trajectory) -> Result<()> {
    let (n, m) = (sc.n(), sc.m());
    let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"));
    p.equal_aspect = true;
    for i in 0..n {
        let colour = robot_colour(i);
        for l in 0..m {
            let c = 2 * (n + l);
            let (x, y): (Vec<f64>, Vec<f64>) =
                tr.xhat.iter().map(|e| (e[i][c], e[i][c + 1])).unzip();
            p.curves.push(
                Curve::new(format!("robot {i}'s landmark estimates"), x, y)
                    .with_style(Style::line().colour(colour).width(1.6).dash(Dash::Dashed)),
            );
        }
    }
    for i in 0..n {
        let (x, y): (Vec<f64>, Vec<f64>) = tr.x.iter().map(|s| (s[2 * i], s[2 * i + 1])).unzip();
        p.curves.push(
            Curve::new("robot paths", x, y).with_style(Style::line().colour(PATH).width(2.5)),
        );
    }
    if let (Some(first), Some(last)) = (tr.x.first(), tr.x.last()) {
        let (lx, ly): (Vec<f64>, Vec<f64>) = (0..m)
            .map(|l| (first[2 * (n + l)], first[2 * (n + l) + 1]))
            .unzip();
        for (l, (&x, &y)) in lx.iter().zip(&ly).enumerate() {
            p.labels.push(Label {
                offset: (7.0, -7.0),
                h: HAlign::Left,
                v: VAlign::Bottom,
                size: 16.0,
                ..Label::new(x, y, format!("m_{{{l}}}"))
            });
        }
        p.curves.push(
            Curve::new("landmarks (true)", lx, ly).with_style(
                Style::markers(Marker::new(Shape::Cross, 13.0)).colour(palette::MARKER),
            ),
        );
        let (sx, sy): (Vec<f64>, Vec<f64>) =
            (0..n).map(|i| (first[2 * i], first[2 * i + 1])).unzip();
        p.curves
            .push(Curve::new("initial positions", sx, sy).with_style(
                Style::markers(Marker::new(Shape::Circle, 12.0).hollow()).colour(palette::MARKER),
            ));
        let (ex, ey): (Vec<f64>, Vec<f64>) = (0..n).map(|i| (last[2 * i], last[2 * i + 1])).unzip();
        p.curves.push(
            Curve::new("final positions", ex, ey).with_style(
                Style::markers(Marker::new(Shape::Diamond, 13.0)).colour(palette::MARKER),
            ),
        );
    }
    let fig = Figure::single(
        format!("{}: robot paths and estimated landmark tracks", sc.name()),
        p,
    )
    .with_size(1000, 900);
    let rep = fig.render(path)?;
    warn(path, &rep);
    Ok(())
}

/// Error curves on a log scale: each robot's `‖x̂_i − x‖`, the formation and centroid errors. Exact zeros
/// (before a disturbance, with exact initial estimates) cannot be drawn on a log axis: they are left out, and
/// the figure's note says how many.
pub fn errors(path: &Path, sc: &Scenario, tr: &Trajectory) -> Result<()> {
    let n = sc.n();
    let t = tr.times.clone();
    let mut p = Panel::new(Axis::linear("time t", "s").tight(), Axis::log("error", "m"));
    if let Some(d) = sc.disturbance() {
        p.shades.push(Shade {
            from: d.start,
            to: d.end,
            label: "disturbance window".into(),
            colour: Rgb(228, 228, 228),
        });
    }
    for i in 0..n {
        let e: Vec<f64> = (0..t.len()).map(|k| tr.error(k, i).norm()).collect();
        p.curves.push(
            Curve::new(
                format!("robot {i}: estimation error ‖x̂_{{{i}}} − x‖"),
                t.clone(),
                e,
            )
            .with_style(Style::line().colour(robot_colour(i)).width(1.6)),
        );
    }
    let form: Vec<f64> = tr.x.iter().map(|x| sc.formation_error(x)).collect();
    p.curves.push(
        Curve::new("formation error", t.clone(), form)
            .with_style(Style::line().colour(PATH).width(2.5)),
    );
    let cent: Vec<f64> =
        tr.x.iter()
            .zip(&tr.times)
            .map(|(x, &tk)| sc.centroid_error(tk, x))
            .collect();
    p.curves.push(
        Curve::new("centroid error ‖p_{c} − p^{*}_{c}‖", t, cent).with_style(
            Style::line()
                .colour(palette::MARKER)
                .width(1.6)
                .dash(Dash::DashDot),
        ),
    );
    let fig = Figure::single(
        format!("{}: estimation, formation and centroid errors", sc.name()),
        p,
    )
    .with_size(1000, 650);
    let rep = fig.render(path)?;
    warn(path, &rep);
    Ok(())
}
