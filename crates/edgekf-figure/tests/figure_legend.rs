//! Legend placement against the data's bounding boxes, and swatches that show the curve's real style.

use edgekf_figure::{
    palette, Axis, Canvas, Curve, Dash, Figure, LegendMode, Panel, PanelReport, Placement, PxRect,
    Rgb, Style,
};

/// Pixel bounding box of a curve's points.
fn bbox(p: &PanelReport, x: &[f64], y: &[f64]) -> PxRect {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (&a, &b) in x.iter().zip(y) {
        let (px, py) = p.to_px(a, b);
        x0 = x0.min(px);
        x1 = x1.max(px);
        y0 = y0.min(py);
        y1 = y1.max(py);
    }
    PxRect::new(x0, y0, x1, y1).grow(2.0)
}

#[test]
fn the_legend_avoids_the_data() {
    // Upper-right and lower-left clusters leave the upper left and lower right free.
    let xa: Vec<f64> = (0..200).map(|k| 6.0 + 4.0 * f64::from(k) / 200.0).collect();
    let ya: Vec<f64> = xa.iter().map(|x| 8.0 + (x * 3.0).sin()).collect();
    let xb: Vec<f64> = (0..200).map(|k| 4.0 * f64::from(k) / 200.0).collect();
    let yb: Vec<f64> = xb.iter().map(|x| 1.0 + (x * 2.0).cos()).collect();
    let fig = Figure::single(
        "clusters",
        Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"))
            .with_curve(Curve::new("upper right", xa.clone(), ya.clone()))
            .with_curve(Curve::new("lower left", xb.clone(), yb.clone())),
    );
    let (_, rep) = fig.draw();
    let p = &rep.panels[0];
    let l = p.legend.as_ref().expect("legend drawn");
    assert!(
        p.plot.contains(&l.rect),
        "inside the plot: {:?} in {:?}",
        l.rect,
        p.plot
    );
    for (x, y) in [(&xa, &ya), (&xb, &yb)] {
        let b = bbox(p, x, y);
        assert!(
            !l.rect.intersects(&b),
            "legend {:?} over data {b:?}",
            l.rect
        );
    }
    assert_eq!(l.covered, 0);
    assert!(
        matches!(l.placement, Placement::UpperLeft | Placement::LowerRight),
        "{:?}",
        l.placement
    );
}

#[test]
fn a_decaying_curve_keeps_the_upper_right_corner_free_on_a_log_axis() {
    let t: Vec<f64> = (1..=3000).map(|k| f64::from(k) * 0.01).collect();
    let mut p = Panel::new(Axis::linear("t", "s").tight(), Axis::log("ε", "m"));
    for (k, (a, b)) in [(1.0, 0.5), (0.5, 0.05), (0.3, 0.01)].iter().enumerate() {
        let y: Vec<f64> = t.iter().map(|&t| b + a * (-3.0 * t).exp()).collect();
        p.curves
            .push(Curve::new(format!("filter {k}"), t.clone(), y));
    }
    let (_, rep) = Figure::single("decay", p.clone()).draw();
    let r = &rep.panels[0];
    let l = r.legend.as_ref().expect("legend");
    for c in &p.curves {
        // The legend may share the plot's corners with the data's bounding box, but not its pixels: check
        // every point.
        for (&x, &y) in c.x.iter().zip(&c.y) {
            let (px, py) = r.to_px(x, y);
            assert!(
                !l.rect.grow(1.0).contains(&PxRect::new(px, py, px, py)),
                "{} at t = {x}",
                c.label
            );
        }
    }
}

#[test]
fn no_free_corner_puts_the_legend_outside() {
    // Noise over the whole plot area.
    let x: Vec<f64> = (0..4000).map(f64::from).collect();
    let y: Vec<f64> = (0..4000u64).map(|k| ((k * 7919) % 1000) as f64).collect();
    let fig = Figure::single(
        "noise",
        Panel::new(Axis::linear("k", ""), Axis::linear("v", "m"))
            .with_curve(Curve::new("noise", x, y))
            .with_curve(Curve::new("level", vec![0.0, 4000.0], vec![500.0, 500.0])),
    );
    let (canvas, rep) = fig.draw();
    let p = &rep.panels[0];
    let l = p.legend.as_ref().expect("legend");
    assert_eq!(l.placement, Placement::OutsideRight);
    assert!(l.rect.x0 > p.plot.x1);
    assert!(l.rect.x1 <= f64::from(canvas.width()));
}

#[test]
fn a_hidden_legend_is_not_drawn() {
    let mut panel = Panel::new(Axis::linear("x", ""), Axis::linear("y", ""))
        .with_curve(Curve::new("a", vec![0.0, 1.0], vec![0.0, 1.0]));
    panel.legend = LegendMode::Hidden;
    let (_, rep) = Figure::single("", panel).draw();
    assert!(rep.panels[0].legend.is_none());
}

/// Runs of pixels close to `c` along the legend row where `c` is most frequent.
fn swatch_runs(canvas: &Canvas, r: &PxRect, c: Rgb) -> usize {
    let near = |p: Rgb| palette::distance(p, c) < 80.0;
    let (x0, x1) = (r.x0 as i32, r.x1 as i32);
    let best = (r.y0 as i32..r.y1 as i32)
        .max_by_key(|&y| (x0..x1).filter(|&x| near(canvas.pixel(x, y))).count())
        .expect("rows");
    let mut runs = 0;
    let mut inside = false;
    for x in x0..x1 {
        let on = near(canvas.pixel(x, best));
        if on && !inside {
            runs += 1;
        }
        inside = on;
    }
    runs
}

#[test]
fn dashed_entries_get_dashed_swatches() {
    let colour = Rgb(213, 94, 0);
    let make = |dash: Dash| {
        let fig = Figure::single(
            "swatch",
            Panel::new(Axis::linear("x", ""), Axis::linear("y", "")).with_curve(
                Curve::new("curve", vec![0.0, 1.0], vec![0.0, 0.0])
                    .with_style(Style::line().colour(colour).dash(dash)),
            ),
        );
        let (canvas, rep) = fig.draw();
        let r = rep.panels[0].legend.as_ref().expect("legend").rect;
        swatch_runs(&canvas, &r, colour)
    };
    assert_eq!(make(Dash::Solid), 1);
    assert!(
        make(Dash::Dashed) >= 3,
        "dashed swatch shows {} dashes",
        make(Dash::Dashed)
    );
    assert!(make(Dash::Dotted) >= 5);
}
