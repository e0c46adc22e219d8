//! Figures for the SLAM observer: a Fig. 3-style map of paths and landmark estimates, and error curves.

use anyhow::Result;
use edgekf_slam::{Scenario, Trajectory};
use plotters::prelude::*;
use std::path::Path;

/// Colours of the robots' estimate tracks (green, red and black are taken by paths, starts and ends).
const ROBOT_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 140),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn robot_colour(i: usize) -> RGBColor {
    ROBOT_COLOURS[i % ROBOT_COLOURS.len()]
}

/// Fig. 3 of the paper: robot paths (green), red start circles, black end diamonds, each robot's estimated
/// landmark tracks dashed (one colour per robot), true landmarks as black crosses.
pub fn paths(path: &Path, sc: &Scenario, tr: &Trajectory) -> Result<()> {
    crate::plot::register_fonts();
    let (n, m) = (sc.n(), sc.m());
    let (w, h) = (1000u32, 900u32);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut grow = |x: f64, y: f64| {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    };
    for (k, x) in tr.x.iter().enumerate() {
        for i in 0..n {
            grow(x[2 * i], x[2 * i + 1]);
            for l in 0..m {
                let c = 2 * (n + l);
                grow(tr.xhat[k][i][c], tr.xhat[k][i][c + 1]);
            }
        }
    }
    for l in 0..m {
        let c = 2 * (n + l);
        grow(tr.x[0][c], tr.x[0][c + 1]);
    }
    // Equal scales on both axes: widen the shorter span to the plotting area's aspect ratio.
    let (area_w, area_h) = (f64::from(w - 100), f64::from(h - 110));
    let (mut sx, mut sy) = (
        (hi.0 - lo.0).max(1e-9) * 1.08,
        (hi.1 - lo.1).max(1e-9) * 1.08,
    );
    if sx / sy < area_w / area_h {
        sx = sy * area_w / area_h;
    } else {
        sy = sx * area_h / area_w;
    }
    let (cx, cy) = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: robot paths and estimated landmark tracks", sc.name),
            ("sans-serif", 24),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(
            (cx - sx / 2.0)..(cx + sx / 2.0),
            (cy - sy / 2.0)..(cy + sy / 2.0),
        )?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    for i in 0..n {
        let colour = robot_colour(i);
        for l in 0..m {
            let c = 2 * (n + l);
            let pts: Vec<(f64, f64)> = tr.xhat.iter().map(|e| (e[i][c], e[i][c + 1])).collect();
            let series =
                chart.draw_series(DashedLineSeries::new(pts, 7, 5, colour.stroke_width(2)))?;
            if l == 0 {
                series
                    .label(format!("robot {i}'s landmark estimates (dashed)"))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 22, y)], colour.stroke_width(2))
                    });
            }
        }
    }
    for i in 0..n {
        let pts: Vec<(f64, f64)> = tr.x.iter().map(|x| (x[2 * i], x[2 * i + 1])).collect();
        let series = chart.draw_series(LineSeries::new(pts, GREEN.stroke_width(3)))?;
        if i == 0 {
            series.label("robot paths").legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 22, y)], GREEN.stroke_width(3))
            });
        }
    }
    let landmarks: Vec<(f64, f64)> = (0..m)
        .map(|l| (tr.x[0][2 * (n + l)], tr.x[0][2 * (n + l) + 1]))
        .collect();
    chart
        .draw_series(
            landmarks
                .iter()
                .map(|&p| Cross::new(p, 8, BLACK.stroke_width(2))),
        )?
        .label("landmarks (true)")
        .legend(|(x, y)| Cross::new((x + 11, y), 6, BLACK.stroke_width(2)));
    for (l, &(x, y)) in landmarks.iter().enumerate() {
        let label = EmptyElement::at((x, y))
            + Text::new(format!("m{l}"), (8, -22), ("sans-serif", 16).into_font());
        chart.draw_series(std::iter::once(label))?;
    }
    let first = &tr.x[0];
    let last = &tr.x[tr.x.len() - 1];
    chart
        .draw_series(
            (0..n).map(|i| Circle::new((first[2 * i], first[2 * i + 1]), 7, RED.stroke_width(2))),
        )?
        .label("initial positions")
        .legend(|(x, y)| Circle::new((x + 11, y), 6, RED.stroke_width(2)));
    let diamond = |c: (f64, f64)| {
        EmptyElement::at(c) + Polygon::new(vec![(0, -9), (7, 0), (0, 9), (-7, 0)], BLACK.filled())
    };
    chart
        .draw_series((0..n).map(|i| diamond((last[2 * i], last[2 * i + 1]))))?
        .label("final positions")
        .legend(|(x, y)| {
            EmptyElement::at((x + 11, y))
                + Polygon::new(vec![(0, -7), (5, 0), (0, 7), (-5, 0)], BLACK.filled())
        });
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()?;
    root.present()?;
    Ok(())
}

/// Lowest possible bottom of the log axis; exact zeros (e.g. errors with exact initial estimates) sit on the
/// axis bottom, which is a third of the smallest positive value plotted but not below this.
const FLOOR: f64 = 1e-12;

/// Error curves on a log scale: each robot's `‖x̂_i − x‖`, the formation and centroid errors.
pub fn errors(path: &Path, sc: &Scenario, tr: &Trajectory) -> Result<()> {
    crate::plot::register_fonts();
    let n = sc.n();
    let root = BitMapBackend::new(path, (1000, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let est: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..tr.times.len()).map(|k| tr.error(k, i).norm()).collect())
        .collect();
    let form: Vec<f64> = tr.x.iter().map(|x| sc.formation_error(x)).collect();
    let cent: Vec<f64> =
        tr.x.iter()
            .zip(&tr.times)
            .map(|(x, &t)| sc.centroid_error(t, x))
            .collect();
    let all = || est.iter().flatten().chain(&form).chain(&cent).copied();
    let floor = (all().filter(|v| *v > 0.0).fold(f64::INFINITY, f64::min) / 3.0).clamp(FLOOR, 1e-3);
    let top = all().fold(floor * 10.0, f64::max) * 3.0;
    let tmax = *tr.times.last().unwrap_or(&1.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: errors (exact zeros drawn at the axis bottom)", sc.name),
            ("sans-serif", 22),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..tmax, (floor..top).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time t (s)")
        .y_desc("error (m)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()?;
    if let Some(d) = &sc.disturbance {
        let grey = RGBColor(220, 220, 220);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(d.start, floor), (d.end, top)],
                grey.filled(),
            )))?
            .label("disturbance window")
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 22, y + 6)], grey.filled()));
    }
    let clamp = |v: f64| v.max(floor);
    for (i, e) in est.iter().enumerate() {
        let colour = robot_colour(i);
        chart
            .draw_series(LineSeries::new(
                tr.times.iter().zip(e).map(|(&t, &v)| (t, clamp(v))),
                colour.stroke_width(2),
            ))?
            .label(format!("robot {i}: estimation error ‖est_{i} − x‖"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 22, y)], colour.stroke_width(2))
            });
    }
    chart
        .draw_series(LineSeries::new(
            tr.times.iter().zip(&form).map(|(&t, &v)| (t, clamp(v))),
            GREEN.stroke_width(3),
        ))?
        .label("formation error")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], GREEN.stroke_width(3)));
    chart
        .draw_series(LineSeries::new(
            tr.times.iter().zip(&cent).map(|(&t, &v)| (t, clamp(v))),
            BLACK.stroke_width(2),
        ))?
        .label("centroid error ‖p_c − p_c*‖")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()?;
    root.present()?;
    Ok(())
}
