//! Curves that coincide are detected, drawn distinguishably and named in the legend.

use edgekf_figure::{coincide::group_name, Axis, Curve, Figure, Panel, Style};

fn procrustes(t: &[f64], scale: f64) -> Vec<f64> {
    t.iter()
        .map(|&t| (2e-3 + 0.5 * (-0.45 * t).exp()) * scale)
        .collect()
}

fn fig(deviation: f64) -> Figure {
    let t: Vec<f64> = (1..=3000).map(|k| f64::from(k) * 0.01).collect();
    let mut p = Panel::new(
        Axis::linear("t", "s").tight(),
        Axis::log("Procrustes error", "m"),
    );
    for (k, pf) in ["0", "0.25", "0.5", "0.75", "1"].iter().enumerate() {
        p.curves.push(Curve::new(
            format!("rkf-ar P_{{fail}} = {pf}"),
            t.clone(),
            procrustes(&t, 1.0 + deviation * k as f64 / 4.0),
        ));
    }
    p.curves.push(
        Curve::new("û = 0 baseline", t.clone(), procrustes(&t, 3.0))
            .with_style(Style::line().dashed()),
    );
    Figure::single("failures", p)
}

#[test]
fn five_equal_curves_form_one_group() {
    let (_, rep) = fig(5e-4).draw();
    let g = &rep.panels[0].coinciding;
    assert_eq!(g.len(), 1, "{g:?}");
    assert_eq!(g[0].members, vec![0, 1, 2, 3, 4]);
    assert!(g[0].max_deviation <= 1e-3 && g[0].max_deviation > 4e-4);
    assert_eq!(group_name(&g[0].labels), "rkf-ar P_{fail} = 0 … 1");
}

#[test]
fn curves_apart_by_more_than_the_tolerance_do_not() {
    // 2 % apart end to end, neighbours 0.5 %: nothing within 0.1 %.
    let (_, rep) = fig(2e-2).draw();
    assert!(rep.panels[0].coinciding.is_empty());
}

#[test]
fn coinciding_curves_are_drawn_distinguishably() {
    // With detection, the group's members get distinct dashes and markers: the picture differs from the one
    // drawn with detection off, where the last member simply covers the others.
    let on = fig(0.0);
    let mut off = on.clone();
    off.panels[0].coincide_tolerance = None;
    let (a, ra) = on.draw();
    let (b, rb) = off.draw();
    assert_eq!(ra.panels[0].coinciding.len(), 1);
    assert!(rb.panels[0].coinciding.is_empty());
    let differing = a.rgb().iter().zip(b.rgb()).filter(|(p, q)| p != q).count();
    assert!(differing > 3000, "{differing} bytes differ");
    // Every member's colour is visible somewhere in the plot area (none is hidden under another).
    let plot = ra.panels[0].plot;
    for k in 0..5 {
        let c = edgekf_figure::palette::series(k);
        let seen = (plot.y0 as i32..plot.y1 as i32)
            .flat_map(|y| (plot.x0 as i32..plot.x1 as i32).map(move |x| (x, y)))
            .filter(|&(x, y)| edgekf_figure::palette::distance(a.pixel(x, y), c) < 30.0)
            .count();
        assert!(
            seen > 20,
            "member {k} ({c:?}) hardly visible: {seen} pixels"
        );
    }
}

#[test]
fn the_difference_panel_shows_the_relative_differences() {
    let f = fig(4e-4);
    let p = &f.panels[0];
    let groups = p.coinciding();
    assert_eq!(groups.len(), 1);
    let d = p.difference_panel(&groups[0]);
    assert_eq!(d.curves.len(), 4, "one curve per member after the first");
    // Member k is (1 + 1e-4·k) times the first: its relative difference is 1e-4·k throughout.
    for (k, c) in d.curves.iter().enumerate() {
        let want = 1e-4 * (k + 1) as f64;
        assert!(c.y.iter().all(|v| (v - want).abs() < 1e-12), "{}", c.label);
    }
    let (_, rep) = Figure::single("differences", d).draw();
    assert!(rep.panels[0].coinciding.is_empty());
}
