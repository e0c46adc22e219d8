//! From a [`Figure`] to pixels: data sanitising, layout (label areas measured from the longest label), axes,
//! bands, lines, markers, labels, inset and legend.

use std::collections::HashSet;

use super::coincide::{self, Series};
use super::legend::{self, Occupancy, Placement, BAND_WEIGHT, LINE_WEIGHT};
use super::range::{axis_range, AxisReport};
use super::raster::{band_columns, thin_columns, Coverage, Stamp};
use super::text::{self, HAlign, Rotation, VAlign};
use super::Curve;
use super::{
    palette, Axis, Canvas, CurveReport, Dash, Figure, Inset, Label, LegendMode, LegendReport,
    Marker, Panel, PanelReport, PxRect, RenderReport, Rgb, Scale, Shade, Shape, Style, Tick,
};

/// Font sizes in pixels.
struct Fonts {
    title: f32,
    panel_title: f32,
    axis: f32,
    tick: f32,
    legend: f32,
    note: f32,
}

const NORMAL: Fonts = Fonts {
    title: 22.0,
    panel_title: 18.0,
    axis: 17.0,
    tick: 15.0,
    legend: 15.0,
    note: 14.0,
};

const COMPACT: Fonts = Fonts {
    title: 13.0,
    panel_title: 13.0,
    axis: 13.0,
    tick: 12.0,
    legend: 12.0,
    note: 12.0,
};

/// Major and minor tick lengths (outside the frame).
const TICK_MAJOR: f64 = 6.0;
const TICK_MINOR: f64 = 3.0;
/// Markers given to the members of a group of coinciding curves, in order.
const GROUP_SHAPES: [Shape; 6] = [
    Shape::Circle,
    Shape::Square,
    Shape::TriangleUp,
    Shape::Diamond,
    Shape::TriangleDown,
    Shape::Cross,
];
/// Spacing of those markers along the line, in pixels.
const GROUP_MARKER_EVERY: f64 = 90.0;
/// A pixel coordinate never goes further than this many plot sizes outside the plot (keeps clipping exact
/// enough and every number finite).
const FAR: f64 = 1e4;

fn usable(v: f64, s: Scale) -> bool {
    v.is_finite() && (s == Scale::Linear || v > 0.0)
}

/// What a panel draws, borrowed (an inset borrows its panel's curves rather than copying them).
#[derive(Clone, Copy)]
struct Source<'a> {
    title: &'a str,
    curves: &'a [Curve],
    shades: &'a [Shade],
    labels: &'a [Label],
    legend: LegendMode,
    equal_aspect: bool,
    grid: bool,
    inset: Option<&'a Inset>,
    coincide: Option<f64>,
}

impl<'a> From<&'a Panel> for Source<'a> {
    fn from(p: &'a Panel) -> Self {
        Source {
            title: &p.title,
            curves: &p.curves,
            shades: &p.shades,
            labels: &p.labels,
            legend: p.legend,
            equal_aspect: p.equal_aspect,
            grid: p.grid,
            inset: p.inset.as_ref(),
            coincide: p.coincide_tolerance,
        }
    }
}

/// A panel's data, sanitised and styled, ready for layout.
struct Prep<'a> {
    src: Source<'a>,
    x_axis: Axis,
    y_axis: Axis,
    styles: Vec<Style>,
    colours: Vec<Rgb>,
    x: AxisReport,
    y: AxisReport,
    reports: Vec<CurveReport>,
    groups: Vec<super::CoincideGroup>,
}

fn n_points(c: &Curve) -> usize {
    c.x.len().min(c.y.len())
}

/// Sanitises a panel's data; `window` restricts the y range to points with x inside it (insets), and `styles`
/// reuses resolved styles (an inset draws its curves exactly as its panel does).
fn prepare<'a>(
    p: Source<'a>,
    x_axis: Axis,
    y_axis: Axis,
    window: Option<(f64, f64)>,
    styles: Option<(Vec<Style>, Vec<Rgb>)>,
) -> Prep<'a> {
    let (xs, ys) = (x_axis.scale, y_axis.scale);
    let (mut xv, mut yv) = (Vec::new(), Vec::new());
    let reports = sanitise(&p, (xs, ys), window, &mut xv, &mut yv);
    let x_fixed = window.or(x_axis.range);
    let x = axis_range(&mut xv, xs, x_fixed, x_axis.margin);
    let y = axis_range(&mut yv, ys, y_axis.range, y_axis.margin);
    drop((xv, yv));
    let (styles, colours, groups) = match styles {
        Some((s, c)) => (s, c, Vec::new()),
        None => resolve_styles(&p, ys, &y),
    };
    Prep {
        src: p,
        x_axis,
        y_axis,
        styles,
        colours,
        x,
        y,
        reports,
        groups,
    }
}

/// Whether `x` is inside the window (no window: everywhere).
fn in_window(window: Option<(f64, f64)>, x: f64) -> bool {
    window.is_none_or(|(a, b)| x >= a.min(b) && x <= a.max(b))
}

/// On a log y axis, a ±1σ band's lower edge is often far below its mean (σ ≈ mean) or ≤ 0;
/// the axis is not stretched past one decade below the lowest curve value to show it (the
/// band then runs off the bottom), so the curves keep the height of the plot.
fn band_floor(p: &Source<'_>, (xs, ys): (Scale, Scale), window: Option<(f64, f64)>) -> f64 {
    match ys {
        Scale::Log => {
            let m = p
                .curves
                .iter()
                .flat_map(|c| c.x.iter().zip(&c.y).take(n_points(c)))
                .filter(|(x, y)| usable(**x, xs) && usable(**y, ys) && in_window(window, **x))
                .map(|(_, y)| *y)
                .fold(f64::INFINITY, f64::min);
            if m.is_finite() {
                m / 10.0
            } else {
                0.0
            }
        }
        Scale::Linear => f64::NEG_INFINITY,
    }
}

/// The values that span the axes (`xv`, `yv`: usable points, band edges and shades in the
/// window) and each curve's report of what was left out.
fn sanitise(
    p: &Source<'_>,
    (xs, ys): (Scale, Scale),
    window: Option<(f64, f64)>,
    xv: &mut Vec<f64>,
    yv: &mut Vec<f64>,
) -> Vec<CurveReport> {
    let in_window = |x: f64| in_window(window, x);
    let band_floor = band_floor(p, (xs, ys), window);
    let mut reports = Vec::with_capacity(p.curves.len());
    for c in p.curves {
        let n = n_points(c);
        let mut r = CurveReport {
            label: c.label.clone(),
            points: n,
            ..CurveReport::default()
        };
        for i in 0..n {
            let (x, y) = (c.x[i], c.y[i]);
            if !(x.is_finite() && y.is_finite()) {
                r.non_finite += 1;
                continue;
            }
            if !(usable(x, xs) && usable(y, ys)) {
                r.non_positive += 1;
                // A point left out of a log y axis still spans the x axis (a time axis shows the whole run).
                if usable(x, xs) && in_window(x) {
                    xv.push(x);
                }
                continue;
            }
            if !in_window(x) {
                continue;
            }
            xv.push(x);
            yv.push(y);
        }
        if let Some((lo, hi)) = &c.band {
            for i in 0..n.min(lo.len()).min(hi.len()) {
                if !(usable(c.x[i], xs) && in_window(c.x[i])) {
                    continue;
                }
                for v in [lo[i], hi[i]] {
                    if usable(v, ys) && v >= band_floor {
                        yv.push(v);
                    } else {
                        r.band_outside += 1;
                    }
                }
            }
        }
        reports.push(r);
    }
    for s in p.shades {
        for v in [s.from, s.to] {
            if usable(v, xs) && in_window(v) {
                xv.push(v);
            }
        }
    }
    reports
}

/// The curves' styles and colours (the palette in order for curves without a colour), and the
/// groups of coinciding curves, whose members get distinct dashes and markers.
fn resolve_styles(
    p: &Source<'_>,
    ys: Scale,
    y: &AxisReport,
) -> (Vec<Style>, Vec<Rgb>, Vec<super::CoincideGroup>) {
    let mut auto = 0;
    let mut styles: Vec<Style> = p.curves.iter().map(|c| c.style.clone()).collect();
    let colours: Vec<Rgb> = styles
        .iter()
        .map(|s| {
            s.colour.unwrap_or_else(|| {
                auto += 1;
                palette::series(auto - 1)
            })
        })
        .collect();
    let groups = match p.coincide {
        Some(tol) if tol > 0.0 && tol.is_finite() => coinciding(p, tol, ys, y),
        _ => Vec::new(),
    };
    for g in &groups {
        let len = g.members.len() as f64;
        for (m, &i) in g.members.iter().enumerate() {
            let s = &mut styles[i];
            s.dash = Some(Dash::ALL[m % Dash::ALL.len()]);
            s.marker = Some(
                Marker::new(GROUP_SHAPES[m % GROUP_SHAPES.len()], 7.0).spaced(
                    GROUP_MARKER_EVERY,
                    GROUP_MARKER_EVERY * (m as f64 + 0.5) / len,
                ),
            );
        }
    }
    (styles, colours, groups)
}

/// The groups of curves that coincide within `tol` of the y range. Only curves with a label of
/// their own: a family sharing one label (landmark tracks, links) is one legend entry and is
/// not compared.
fn coinciding(p: &Source<'_>, tol: f64, ys: Scale, y: &AxisReport) -> Vec<super::CoincideGroup> {
    let mut count = std::collections::HashMap::new();
    for c in p.curves {
        *count.entry(c.label.as_str()).or_insert(0usize) += 1;
    }
    let series: Vec<Option<Series>> = p
        .curves
        .iter()
        .map(|c| {
            let n = n_points(c);
            let eligible = c.style.dash.is_some()
                && !c.label.is_empty()
                && count[c.label.as_str()] == 1
                && n >= 2;
            eligible.then(|| Series {
                x: &c.x[..n],
                y: &c.y[..n],
            })
        })
        .collect();
    let labels: Vec<String> = p.curves.iter().map(|c| c.label.clone()).collect();
    coincide::find(&series, &labels, tol, ys, y.hi - y.lo)
}

/// Data → pixel along one axis.
#[derive(Clone, Copy, Debug)]
struct Map {
    scale: Scale,
    lo: f64,
    hi: f64,
    p0: f64,
    p1: f64,
}

impl Map {
    fn new(scale: Scale, a: &AxisReport, p0: f64, p1: f64) -> Self {
        let (lo, hi) = match scale {
            Scale::Linear => (a.lo, a.hi),
            Scale::Log => (a.lo.log10(), a.hi.log10()),
        };
        Map {
            scale,
            lo,
            hi,
            p0,
            p1,
        }
    }
    /// Pixel of `v`; NaN when `v` is not on the axis (non-finite, ≤ 0 on a log axis).
    fn px(&self, v: f64) -> f64 {
        let u = match self.scale {
            Scale::Linear => v,
            Scale::Log if v > 0.0 => v.log10(),
            Scale::Log => return f64::NAN,
        };
        if !u.is_finite() {
            return f64::NAN;
        }
        // Halves keep the difference finite for values near ±f64::MAX.
        let t = (u / 2.0 - self.lo / 2.0) / (self.hi / 2.0 - self.lo / 2.0);
        self.p0 + t.clamp(-FAR, FAR) * (self.p1 - self.p0)
    }
}

/// Ticks over `[lo, hi]` whose labels do not collide on an axis of `len` pixels.
fn fit_ticks(a: &AxisReport, scale: Scale, len: f64, horizontal: bool, font: f32) -> Vec<Tick> {
    let len = len.max(1.0);
    let per = if horizontal { 85.0 } else { 42.0 };
    let mut n = ((len / per).floor() as usize).clamp(2, 12);
    let decades = if scale == Scale::Log {
        (a.hi.log10() - a.lo.log10()).max(1e-9)
    } else {
        1.0
    };
    loop {
        let t = match scale {
            Scale::Linear => super::ticks::linear_ticks(a.lo, a.hi, n),
            Scale::Log => super::ticks::log_ticks(a.lo, a.hi, n, len / decades),
        };
        let map = Map::new(scale, a, 0.0, len);
        let labelled: Vec<(f64, f64)> = t
            .iter()
            .filter_map(|t| {
                t.label.as_ref().map(|l| {
                    let e = text::measure(l, font);
                    (
                        map.px(t.value),
                        if horizontal {
                            f64::from(e.width)
                        } else {
                            f64::from(e.height())
                        },
                    )
                })
            })
            .collect();
        let gap = if horizontal { 14.0 } else { 4.0 };
        let ok = labelled
            .windows(2)
            .all(|w| (w[1].0 - w[0].0).abs() >= (w[0].1 + w[1].1) / 2.0 + gap);
        if ok || n <= 2 {
            return t;
        }
        n -= 1;
    }
}

/// A panel's layout.
struct Layout {
    plot: PxRect,
    x: AxisReport,
    y: AxisReport,
    xt: Vec<Tick>,
    yt: Vec<Tick>,
    xm: Map,
    ym: Map,
}

fn layout(
    area: PxRect,
    p: &Prep,
    f: &Fonts,
    right_reserve: f64,
    compact: bool,
    min_left: f64,
) -> Layout {
    let title_h = if p.src.title.is_empty() {
        0.0
    } else {
        f64::from(text::measure(p.src.title, f.panel_title).height()) + 6.0
    };
    let x_title = p.x_axis.title();
    let y_title = p.y_axis.title();
    let has_xl = !compact && !x_title.is_empty();
    let has_yl = !compact && !y_title.is_empty();
    let tick_h = f64::from(text::measure("0", f.tick).height());
    let top = area.y0 + title_h + tick_h * 0.5 + 4.0;
    let axis_h = f64::from(text::measure("Xy", f.axis).height());
    let bottom = area.y1 - if has_xl { axis_h + 6.0 } else { 0.0 } - tick_h - TICK_MAJOR - 6.0;
    let (mut x, mut y) = (p.x.clone(), p.y.clone());
    let (mut xt, mut yt) = (Vec::new(), Vec::new());
    let mut right_over = 8.0f64;
    let mut plot = area;
    for _ in 0..3 {
        let height = (bottom - top).max(10.0);
        yt = fit_ticks(&y, p.y_axis.scale, height, false, f.tick);
        let yw = yt
            .iter()
            .filter_map(|t| t.label.as_ref())
            .map(|l| f64::from(text::measure(l, f.tick).width))
            .fold(0.0, f64::max);
        let left =
            (area.x0 + 6.0 + if has_yl { axis_h + 8.0 } else { 0.0 } + yw + 5.0 + TICK_MAJOR)
                .max(area.x0 + min_left);
        let right = area.x1 - right_reserve - right_over;
        let width = (right - left).max(10.0);
        plot = PxRect::new(
            left.round(),
            top.round(),
            (left + width).round(),
            (top + height).round(),
        );
        if p.src.equal_aspect && p.x_axis.scale == Scale::Linear && p.y_axis.scale == Scale::Linear
        {
            (x, y) = (p.x.clone(), p.y.clone());
            let ux = (x.hi - x.lo) / plot.width();
            let uy = (y.hi - y.lo) / plot.height();
            if ux > uy {
                let (c, h) = (y.lo / 2.0 + y.hi / 2.0, ux * plot.height() / 2.0);
                (y.lo, y.hi) = (c - h, c + h);
            } else {
                let (c, h) = (x.lo / 2.0 + x.hi / 2.0, uy * plot.width() / 2.0);
                (x.lo, x.hi) = (c - h, c + h);
            }
            yt = fit_ticks(&y, p.y_axis.scale, plot.height(), false, f.tick);
        }
        xt = fit_ticks(&x, p.x_axis.scale, plot.width(), true, f.tick);
        // How far the labels reach past the plot's right edge decides the right margin.
        let xm = Map::new(p.x_axis.scale, &x, plot.x0, plot.x1);
        let over = xt
            .iter()
            .filter_map(|t| t.label.as_ref().map(|l| (t.value, l)))
            .map(|(v, l)| xm.px(v) + f64::from(text::measure(l, f.tick).width) / 2.0 - plot.x1)
            .fold(0.0, f64::max);
        let want = over + 6.0;
        if (want - right_over).abs() < 1.0 {
            break;
        }
        right_over = want.max(6.0);
    }
    let xm = Map::new(p.x_axis.scale, &x, plot.x0, plot.x1);
    let ym = Map::new(p.y_axis.scale, &y, plot.y1, plot.y0);
    Layout {
        plot,
        x,
        y,
        xt,
        yt,
        xm,
        ym,
    }
}

/// Draws text into a fresh coverage buffer and composites it (optionally on a white halo); returns its box.
#[allow(clippy::too_many_arguments)]
fn put_text(
    canvas: &mut Canvas,
    s: &str,
    size: f32,
    at: (f64, f64),
    h: HAlign,
    v: VAlign,
    rot: Rotation,
    colour: Rgb,
    halo: bool,
) -> PxRect {
    let l = text::layout(s, size);
    let (x0, y0, x1, y1) = l.bounds((at.0 as f32, at.1 as f32), h, v, rot);
    let r = PxRect::new(f64::from(x0), f64::from(y0), f64::from(x1), f64::from(y1));
    let mut cov = Coverage::new(r.grow(4.0));
    l.rasterise((at.0 as f32, at.1 as f32), h, v, rot, |x, y, c| {
        cov.put(x, y, c)
    });
    if halo {
        cov.dilated(2.0).composite(canvas, Rgb::WHITE, 0.9);
    }
    cov.composite(canvas, colour, 1.0);
    r
}

/// Greedy word wrap to `width` pixels.
fn wrap(s: &str, size: f32, width: f64) -> Vec<String> {
    let mut lines = Vec::new();
    let mut cur = String::new();
    for w in s.split(' ') {
        let cand = if cur.is_empty() {
            w.to_string()
        } else {
            format!("{cur} {w}")
        };
        if !cur.is_empty() && f64::from(text::measure(&cand, size).width) > width {
            lines.push(std::mem::replace(&mut cur, w.to_string()));
        } else {
            cur = cand;
        }
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

/// Renders a figure.
pub(super) fn figure(fig: &Figure) -> (Canvas, RenderReport) {
    let w = fig.size.0.clamp(120, 12_000);
    let h = fig.size.1.clamp(90, 12_000);
    let mut canvas = Canvas::new(w, h);
    let f = &NORMAL;
    let top = draw_title(&mut canvas, &fig.title, f, w);
    let preps: Vec<Prep> = fig
        .panels
        .iter()
        .map(|p| prepare(p.into(), p.x_axis.clone(), p.y_axis.clone(), None, None))
        .collect();
    let note_lines: Vec<String> = notes(fig, &preps)
        .iter()
        .flat_map(|n| wrap(n, f.note, f64::from(w) - 40.0))
        .collect();
    let line_h = f64::from(f.note) * 1.35;
    let notes_h = if note_lines.is_empty() {
        0.0
    } else {
        line_h * note_lines.len() as f64 + 8.0
    };
    let grid = PxRect::new(
        6.0,
        top,
        f64::from(w) - 6.0,
        (f64::from(h) - 6.0 - notes_h).max(top + 20.0),
    );
    let panels = draw_grid(&mut canvas, grid, fig.columns, &preps, f);
    let mut y = grid.y1 + 6.0;
    for l in &note_lines {
        put_text(
            &mut canvas,
            l,
            f.note,
            (20.0, y),
            HAlign::Left,
            VAlign::Top,
            Rotation::None,
            palette::NOTE,
            false,
        );
        y += line_h;
    }
    (
        canvas,
        RenderReport {
            size: (w, h),
            panels,
        },
    )
}

/// Draws the figure's title (if any) centred at the top; returns the y under it.
fn draw_title(canvas: &mut Canvas, title: &str, f: &Fonts, w: u32) -> f64 {
    let mut top = 8.0;
    if !title.is_empty() {
        let r = put_text(
            canvas,
            title,
            f.title,
            (f64::from(w) / 2.0, top),
            HAlign::Center,
            VAlign::Top,
            Rotation::None,
            Rgb::BLACK,
            false,
        );
        top = r.y1 + 8.0;
    }
    top
}

/// The notes under the figure: the caller's, then what the reader should know about the data.
fn notes(fig: &Figure, preps: &[Prep]) -> Vec<String> {
    let mut notes = fig.notes.clone();
    if fig.auto_notes {
        let many = preps.len() > 1;
        for p in preps {
            let rep = panel_report(p, None);
            for wmsg in rep.warnings() {
                notes.push(if many && !p.src.title.is_empty() {
                    format!("{}: {wmsg}", text::plain(p.src.title))
                } else {
                    format!("Note: {wmsg}.")
                });
            }
        }
    }
    notes
}

/// Draws the panels in a grid of `columns` columns filling `grid`; returns their reports.
fn draw_grid(
    canvas: &mut Canvas,
    grid: PxRect,
    columns: usize,
    preps: &[Prep],
    f: &Fonts,
) -> Vec<PanelReport> {
    let cols = columns.max(1).min(preps.len().max(1));
    let rows = preps.len().div_ceil(cols).max(1);
    let (cw, ch) = (grid.width() / cols as f64, grid.height() / rows as f64);
    let area = |k: usize| {
        let (r, c) = (k / cols, k % cols);
        PxRect::new(
            grid.x0 + cw * c as f64,
            grid.y0 + ch * r as f64,
            grid.x0 + cw * (c as f64 + 1.0),
            grid.y0 + ch * (r as f64 + 1.0),
        )
    };
    // Panels of one grid column share the left edge of their plot areas.
    let mut left = vec![0.0f64; cols];
    if rows > 1 {
        for (k, p) in preps.iter().enumerate() {
            let a = area(k);
            let lay = layout(a, p, f, 0.0, false, 0.0);
            left[k % cols] = left[k % cols].max(lay.plot.x0 - a.x0);
        }
    }
    let mut panels = Vec::with_capacity(preps.len());
    for (k, p) in preps.iter().enumerate() {
        panels.push(draw_panel(canvas, area(k), p, f, false, left[k % cols]));
    }
    panels
}

fn panel_report(p: &Prep, lay: Option<&Layout>) -> PanelReport {
    PanelReport {
        title: p.src.title.to_string(),
        plot: lay.map_or(PxRect::new(0.0, 0.0, 1.0, 1.0), |l| l.plot),
        x_scale: p.x_axis.scale,
        y_scale: p.y_axis.scale,
        x: lay.map_or_else(|| p.x.clone(), |l| l.x.clone()),
        y: lay.map_or_else(|| p.y.clone(), |l| l.y.clone()),
        x_ticks: lay.map_or_else(Vec::new, |l| l.xt.clone()),
        y_ticks: lay.map_or_else(Vec::new, |l| l.yt.clone()),
        curves: p.reports.clone(),
        coinciding: p.groups.clone(),
        legend: None,
        inset: None,
        texts: Vec::new(),
    }
}

/// One legend row.
enum Entry {
    Curve {
        label: String,
        colour: Rgb,
        style: Style,
        band: bool,
    },
    Shade {
        label: String,
        colour: Rgb,
    },
    Note(String),
}

fn entries(p: &Prep) -> Vec<Entry> {
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for s in p.src.shades.iter().filter(|s| !s.label.is_empty()) {
        if seen.insert(s.label.clone()) {
            out.push(Entry::Shade {
                label: s.label.clone(),
                colour: s.colour,
            });
        }
    }
    for (i, c) in p.src.curves.iter().enumerate() {
        if c.label.is_empty() || !seen.insert(c.label.clone()) {
            continue;
        }
        out.push(Entry::Curve {
            label: c.label.clone(),
            colour: p.colours[i],
            style: p.styles[i].clone(),
            band: c.band.is_some(),
        });
    }
    for g in &p.groups {
        out.push(Entry::Note(format!(
            "≡ {}: coincide within {}",
            coincide::group_name(&g.labels),
            percent(g.tolerance)
        )));
    }
    out
}

fn percent(t: f64) -> String {
    let p = t * 100.0;
    if p >= 1.0 {
        format!("{p:.0} %")
    } else {
        let d = (-p.log10().floor()) as usize;
        format!("{p:.d$} %")
    }
}

const SWATCH: f64 = 40.0;

fn legend_size(es: &[Entry], f: &Fonts) -> (f64, f64) {
    let row = f64::from(f.legend) * 1.5;
    let w = es
        .iter()
        .map(|e| match e {
            Entry::Curve { label, .. } | Entry::Shade { label, .. } => {
                SWATCH + 8.0 + f64::from(text::measure(label, f.legend).width)
            }
            Entry::Note(n) => f64::from(text::measure(n, f.legend).width),
        })
        .fold(0.0, f64::max);
    (w + 20.0, row * es.len() as f64 + 12.0)
}

fn draw_legend(canvas: &mut Canvas, r: PxRect, es: &[Entry], f: &Fonts) {
    canvas.fill_rect(r, Rgb::WHITE, 0.92);
    canvas.frame(r, Rgb(170, 170, 170));
    let row = f64::from(f.legend) * 1.5;
    for (k, e) in es.iter().enumerate() {
        let cy = r.y0 + 6.0 + row * (k as f64 + 0.5);
        let x0 = r.x0 + 10.0;
        match e {
            Entry::Curve {
                label,
                colour,
                style,
                band,
            } => {
                if *band {
                    canvas.fill_rect(
                        PxRect::new(x0, cy - 7.0, x0 + SWATCH, cy + 7.0),
                        *colour,
                        style.band_opacity,
                    );
                }
                let mut cov = Coverage::new(PxRect::new(
                    x0 - 8.0,
                    cy - 12.0,
                    x0 + SWATCH + 8.0,
                    cy + 12.0,
                ));
                if let Some(d) = style.dash {
                    let w = style.width.clamp(0.5, 6.0);
                    cov.polyline(&[(x0, cy), (x0 + SWATCH, cy)], w, d.pattern(w).as_deref());
                }
                if let Some(m) = style.marker {
                    let st = Stamp::new(m.shape, m.size, m.filled, 1.4);
                    cov.stamp(&st, (x0 + SWATCH / 2.0, cy));
                }
                cov.composite(canvas, *colour, 1.0);
                put_text(
                    canvas,
                    label,
                    f.legend,
                    (x0 + SWATCH + 8.0, cy),
                    HAlign::Left,
                    VAlign::Middle,
                    Rotation::None,
                    Rgb::BLACK,
                    false,
                );
            }
            Entry::Shade { label, colour } => {
                canvas.fill_rect(
                    PxRect::new(x0, cy - 7.0, x0 + SWATCH, cy + 7.0),
                    *colour,
                    1.0,
                );
                put_text(
                    canvas,
                    label,
                    f.legend,
                    (x0 + SWATCH + 8.0, cy),
                    HAlign::Left,
                    VAlign::Middle,
                    Rotation::None,
                    Rgb::BLACK,
                    false,
                );
            }
            Entry::Note(n) => {
                put_text(
                    canvas,
                    n,
                    f.legend,
                    (x0, cy),
                    HAlign::Left,
                    VAlign::Middle,
                    Rotation::None,
                    palette::NOTE,
                    false,
                );
            }
        }
    }
}

/// Draws one panel into `area` (cleared first); returns its report. `min_left` is the least distance from the
/// area's left edge to the plot area (panels of one grid column align their frames).
///
/// The legend and the inset go inside when a spot covers no data, otherwise into a column right of the plot
/// (legend on top, inset under it): at most three passes.
fn draw_panel(
    canvas: &mut Canvas,
    area: PxRect,
    p: &Prep,
    f: &Fonts,
    compact: bool,
    min_left: f64,
) -> PanelReport {
    let es = if compact || p.src.legend == LegendMode::Hidden {
        Vec::new()
    } else {
        entries(p)
    };
    let (lw, lh) = legend_size(&es, f);
    let inset = p.src.inset.filter(|_| !compact);
    let mut legend_out = p.src.legend == LegendMode::Outside && !es.is_empty();
    let mut inset_out = false;
    let gap = 2.0 * legend::INSET_PX;
    let inset_out_w = (area.width() * 0.3).clamp(200.0, 380.0);
    for pass in 0..3 {
        let column = match (legend_out, inset_out) {
            (false, false) => 0.0,
            (true, false) => lw + gap,
            (false, true) => inset_out_w + gap,
            (true, true) => lw.max(inset_out_w) + gap,
        };
        let (lay, mut occ, mut rep) = draw_plot(canvas, area, p, f, (compact, min_left), column);
        // The right column's next free y.
        let col_x = lay.plot.x1 + gap;
        let mut col_y = lay.plot.y0;
        if legend_out {
            col_y += lh + gap;
        }
        if let Some(inset) = inset {
            let placed = if inset_out {
                outside_inset(&lay, (col_x, col_y), inset_out_w)
            } else {
                match place_inset(&lay, inset, &occ) {
                    Some(placed) => Some(placed),
                    None if pass < 2 => {
                        inset_out = true;
                        continue;
                    }
                    None => None,
                }
            };
            if let Some((pl, r)) = placed {
                draw_inset(canvas, r, p, inset);
                occ.add_rect(r, LINE_WEIGHT);
                rep.inset = Some((pl, r));
            }
        }
        if !es.is_empty() {
            let chosen = if legend_out {
                let r = PxRect::new(col_x, lay.plot.y0, col_x + lw, lay.plot.y0 + lh);
                Some((Placement::OutsideRight, r, 0))
            } else {
                legend::choose(lay.plot, lw, lh, &occ)
            };
            match chosen {
                Some((pl, r, cost)) => {
                    draw_legend(canvas, r, &es, f);
                    rep.legend = Some(LegendReport {
                        placement: pl,
                        rect: r,
                        covered: cost,
                    });
                }
                None if pass < 2 => {
                    legend_out = true;
                    continue;
                }
                None => {}
            }
        }
        return rep;
    }
    unreachable!("the third pass always returns")
}

/// One pass of [`draw_panel`] up to the legend and the inset: clears `area`, lays the panel out
/// with `column` pixels kept free on the right, draws axes, data and frame; returns the layout,
/// the pixels the data cover, and the report.
fn draw_plot(
    canvas: &mut Canvas,
    area: PxRect,
    p: &Prep,
    f: &Fonts,
    (compact, min_left): (bool, f64),
    column: f64,
) -> (Layout, Occupancy, PanelReport) {
    canvas.fill_rect(area, Rgb::WHITE, 1.0);
    let lay = layout(area, p, f, column, compact, min_left);
    let mut occ = Occupancy::new(lay.plot);
    let texts = draw_axes(canvas, area, p, &lay, f, compact);
    let vertices = draw_data(canvas, p, &lay, &mut occ);
    canvas.frame(lay.plot, palette::AXIS);
    let mut rep = panel_report(p, Some(&lay));
    rep.texts = texts;
    for (r, v) in rep.curves.iter_mut().zip(vertices) {
        r.vertices_drawn = v;
    }
    if p.x.empty || p.y.empty {
        put_text(
            canvas,
            "no finite data",
            f.axis,
            (
                (lay.plot.x0 + lay.plot.x1) / 2.0,
                (lay.plot.y0 + lay.plot.y1) / 2.0,
            ),
            HAlign::Center,
            VAlign::Middle,
            Rotation::None,
            palette::NOTE,
            false,
        );
    }
    (lay, occ, rep)
}

/// The inset's spot in the column right of the plot, from `(x, y)`, `width` wide, if it is at
/// least 80 pixels high.
fn outside_inset(lay: &Layout, (x, y): (f64, f64), width: f64) -> Option<(Placement, PxRect)> {
    let ih = (width * 0.75).min(lay.plot.y1 - y).max(0.0);
    (ih >= 80.0).then(|| {
        (
            Placement::OutsideRight,
            PxRect::new(x, y, x + width, y + ih),
        )
    })
}

/// A spot inside the plot for the inset that covers no data, if there is one.
fn place_inset(lay: &Layout, inset: &Inset, occ: &Occupancy) -> Option<(Placement, PxRect)> {
    let iw = (lay.plot.width() * inset.size.0.clamp(0.1, 0.9))
        .max(170.0)
        .min(lay.plot.width() - 20.0);
    let ih = (lay.plot.height() * inset.size.1.clamp(0.1, 0.9))
        .max(120.0)
        .min(lay.plot.height() - 20.0);
    legend::choose(lay.plot, iw, ih, occ).map(|(pl, r, _)| (pl, r))
}

/// Draws shades, grid, ticks, tick labels and titles; returns every text drawn with its box.
fn draw_axes(
    canvas: &mut Canvas,
    area: PxRect,
    p: &Prep,
    lay: &Layout,
    f: &Fonts,
    compact: bool,
) -> Vec<(String, PxRect)> {
    let mut boxes = Vec::new();
    draw_shades(canvas, p, lay);
    if p.src.grid {
        draw_grid_lines(canvas, lay);
    }
    draw_ticks(canvas, lay, f, &mut boxes);
    draw_titles(canvas, area, p, lay, (f, compact), &mut boxes);
    boxes
}

/// Shades behind everything.
fn draw_shades(canvas: &mut Canvas, p: &Prep, lay: &Layout) {
    let pr = lay.plot;
    for s in p.src.shades {
        let (a, b) = (lay.xm.px(s.from), lay.xm.px(s.to));
        if a.is_finite() && b.is_finite() {
            let r = PxRect::new(a.max(pr.x0), pr.y0, b.min(pr.x1), pr.y1);
            if r.x1 > r.x0 {
                canvas.fill_rect(r, s.colour, 1.0);
            }
        }
    }
}

/// Grid lines at the major ticks.
fn draw_grid_lines(canvas: &mut Canvas, lay: &Layout) {
    let pr = lay.plot;
    for t in lay.xt.iter().filter(|t| t.is_major()) {
        let x = lay.xm.px(t.value).round() as i32;
        if (x as f64) > pr.x0 && (x as f64) < pr.x1 - 1.0 {
            for y in pr.y0 as i32..pr.y1 as i32 {
                canvas.blend(x, y, palette::GRID, 1.0);
            }
        }
    }
    for t in lay.yt.iter().filter(|t| t.is_major()) {
        let y = lay.ym.px(t.value).round() as i32;
        if (y as f64) > pr.y0 && (y as f64) < pr.y1 - 1.0 {
            for x in pr.x0 as i32..pr.x1 as i32 {
                canvas.blend(x, y, palette::GRID, 1.0);
            }
        }
    }
}

/// Tick marks and labels of both axes; the labels' boxes go to `boxes`.
fn draw_ticks(canvas: &mut Canvas, lay: &Layout, f: &Fonts, boxes: &mut Vec<(String, PxRect)>) {
    let pr = lay.plot;
    let (bx, by) = (pr.x0 as i32, pr.y1 as i32 - 1);
    for t in &lay.xt {
        let x = lay.xm.px(t.value);
        if !(x >= pr.x0 - 0.5 && x <= pr.x1 + 0.5) {
            continue;
        }
        let xi = (x.round() as i32).min(pr.x1 as i32 - 1);
        let len = if t.is_major() { TICK_MAJOR } else { TICK_MINOR } as i32;
        for k in 1..=len {
            canvas.blend(xi, by + k, palette::AXIS, 1.0);
        }
        if let Some(l) = &t.label {
            let r = put_text(
                canvas,
                l,
                f.tick,
                (x, pr.y1 + TICK_MAJOR + 3.0),
                HAlign::Center,
                VAlign::Top,
                Rotation::None,
                palette::AXIS,
                false,
            );
            boxes.push((l.clone(), r));
        }
    }
    for t in &lay.yt {
        let y = lay.ym.px(t.value);
        if !(y >= pr.y0 - 0.5 && y <= pr.y1 + 0.5) {
            continue;
        }
        let yi = (y.round() as i32).min(pr.y1 as i32 - 1);
        let len = if t.is_major() { TICK_MAJOR } else { TICK_MINOR } as i32;
        for k in 1..=len {
            canvas.blend(bx - k, yi, palette::AXIS, 1.0);
        }
        if let Some(l) = &t.label {
            let r = put_text(
                canvas,
                l,
                f.tick,
                (pr.x0 - TICK_MAJOR - 5.0, y),
                HAlign::Right,
                VAlign::Middle,
                Rotation::None,
                palette::AXIS,
                false,
            );
            boxes.push((l.clone(), r));
        }
    }
}

/// The panel's title and (unless compact) the axis titles; their boxes go to `boxes`.
fn draw_titles(
    canvas: &mut Canvas,
    area: PxRect,
    p: &Prep,
    lay: &Layout,
    (f, compact): (&Fonts, bool),
    boxes: &mut Vec<(String, PxRect)>,
) {
    let pr = lay.plot;
    let mut put = |canvas: &mut Canvas, t: &str, size, at, h, v, rot| {
        let r = put_text(canvas, t, size, at, h, v, rot, Rgb::BLACK, false);
        boxes.push((t.to_string(), r));
    };
    if !p.src.title.is_empty() {
        put(
            canvas,
            p.src.title,
            f.panel_title,
            ((pr.x0 + pr.x1) / 2.0, area.y0 + 2.0),
            HAlign::Center,
            VAlign::Top,
            Rotation::None,
        );
    }
    if !compact {
        let xt = p.x_axis.title();
        if !xt.is_empty() {
            put(
                canvas,
                &xt,
                f.axis,
                ((pr.x0 + pr.x1) / 2.0, area.y1 - 4.0),
                HAlign::Center,
                VAlign::Bottom,
                Rotation::None,
            );
        }
        let yt = p.y_axis.title();
        if !yt.is_empty() {
            put(
                canvas,
                &yt,
                f.axis,
                (area.x0 + 6.0, (pr.y0 + pr.y1) / 2.0),
                HAlign::Center,
                VAlign::Top,
                Rotation::Up,
            );
        }
    }
}

/// Pixel runs of a curve's usable points (a non-usable point breaks the line).
fn runs(c: &Curve, lay: &Layout) -> Vec<Vec<(f64, f64)>> {
    let n = n_points(c);
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for i in 0..n {
        let (px, py) = (lay.xm.px(c.x[i]), lay.ym.px(c.y[i]));
        if px.is_finite() && py.is_finite() {
            cur.push((px, py));
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Draws bands, lines, markers and labels; returns the vertices stroked per curve.
fn draw_data(canvas: &mut Canvas, p: &Prep, lay: &Layout, occ: &mut Occupancy) -> Vec<usize> {
    let pr = lay.plot;
    let clip = PxRect::new(pr.x0 + 1.0, pr.y0 + 1.0, pr.x1 - 1.0, pr.y1 - 1.0);
    // Bands first, so that no band covers a line.
    for (i, c) in p.src.curves.iter().enumerate() {
        if let Some((lo, hi)) = &c.band {
            draw_band(
                canvas,
                (c, lo, hi),
                lay,
                clip,
                (p.colours[i], &p.styles[i]),
                occ,
            );
        }
    }
    let mut vertices = vec![0; p.src.curves.len()];
    let mut markers: Vec<(usize, Vec<(f64, f64)>)> = Vec::new();
    for (i, c) in p.src.curves.iter().enumerate() {
        let (v, pts) = draw_line(canvas, c, lay, clip, (p.colours[i], &p.styles[i]), occ);
        vertices[i] = v;
        if !pts.is_empty() {
            markers.push((i, pts));
        }
    }
    // Markers over all lines.
    for (i, pts) in markers {
        if let Some(m) = p.styles[i].marker {
            draw_markers(canvas, &pts, m, clip, p.colours[i], occ);
        }
    }
    draw_labels(canvas, p, lay, occ);
    vertices
}

/// A curve's ±1σ band (edges ≤ 0 on a log axis reach below the axis).
fn draw_band(
    canvas: &mut Canvas,
    (c, lo, hi): (&Curve, &[f64], &[f64]),
    lay: &Layout,
    clip: PxRect,
    (colour, style): (Rgb, &Style),
    occ: &mut Occupancy,
) {
    let n = n_points(c).min(lo.len()).min(hi.len());
    let below = lay.plot.y1 + 10.0;
    let edge = |v: f64| {
        let y = lay.ym.px(v);
        if y.is_finite() {
            y
        } else if v.is_finite() {
            below // ≤ 0 on a log axis: the band reaches below the axis
        } else {
            f64::NAN
        }
    };
    let (mut xs, mut up, mut dn) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for k in 0..n {
        let (a, b) = (edge(lo[k]), edge(hi[k]));
        xs.push(lay.xm.px(c.x[k]));
        up.push(a.min(b));
        dn.push(a.max(b));
    }
    let mut cov = Coverage::new(clip);
    cov.columns(band_columns(&xs, &up, &dn, clip.x0, clip.x1));
    cov.composite(canvas, colour, style.band_opacity);
    cov.for_each(|x, y, a| {
        if a > 0.2 {
            occ.add(x, y, BAND_WEIGHT);
        }
    });
}

/// A curve's line; returns the vertices stroked and the points for its markers.
fn draw_line(
    canvas: &mut Canvas,
    c: &Curve,
    lay: &Layout,
    clip: PxRect,
    (colour, st): (Rgb, &Style),
    occ: &mut Occupancy,
) -> (usize, Vec<(f64, f64)>) {
    let mut vertices = 0;
    let mut cov = Coverage::new(clip);
    let mut pts_for_markers = Vec::new();
    for r in &runs(c, lay) {
        let t = thin_columns(r);
        vertices += t.len();
        if let Some(d) = st.dash {
            let w = if st.width.is_finite() {
                st.width.clamp(0.3, 20.0)
            } else {
                1.5
            };
            cov.polyline(&t, w, d.pattern(w).as_deref());
        }
        if let Some(m) = st.marker {
            match m.every {
                Some(every) if every.is_finite() && every >= 4.0 => {
                    pts_for_markers.extend(along(&t, every, m.offset, &clip));
                }
                _ => pts_for_markers.extend(r.iter().copied()),
            }
        }
    }
    cov.composite(canvas, colour, 1.0);
    cov.for_each(|x, y, a| {
        if a > 0.25 {
            occ.add(x, y, LINE_WEIGHT);
        }
    });
    (vertices, pts_for_markers)
}

/// A curve's markers at `pts` (once per quarter pixel, those near the plot).
fn draw_markers(
    canvas: &mut Canvas,
    pts: &[(f64, f64)],
    m: Marker,
    clip: PxRect,
    colour: Rgb,
    occ: &mut Occupancy,
) {
    let st = Stamp::new(m.shape, m.size, m.filled, 1.4);
    let mut cov = Coverage::new(clip.grow(0.0));
    let mut seen = HashSet::new();
    for &q in pts {
        if q.0 < clip.x0 - m.size
            || q.0 > clip.x1 + m.size
            || q.1 < clip.y0 - m.size
            || q.1 > clip.y1 + m.size
        {
            continue;
        }
        if seen.insert(((q.0 * 4.0) as i64, (q.1 * 4.0) as i64)) {
            cov.stamp(&st, q);
        }
    }
    cov.composite(canvas, colour, 1.0);
    cov.for_each(|x, y, a| {
        if a > 0.25 {
            occ.add(x, y, LINE_WEIGHT);
        }
    });
}

/// The panel's text labels at data coordinates inside the plot.
fn draw_labels(canvas: &mut Canvas, p: &Prep, lay: &Layout, occ: &mut Occupancy) {
    let pr = lay.plot;
    for l in p.src.labels {
        let (x, y) = (lay.xm.px(l.x), lay.ym.px(l.y));
        if !(x.is_finite() && y.is_finite()) || x < pr.x0 || x > pr.x1 || y < pr.y0 || y > pr.y1 {
            continue;
        }
        let r = put_text(
            canvas,
            &l.text,
            l.size,
            (x + l.offset.0, y + l.offset.1),
            l.h,
            l.v,
            Rotation::None,
            l.colour,
            true,
        );
        occ.add_rect(r, LINE_WEIGHT);
    }
}

/// Points every `every` pixels along a polyline, starting at `offset`, inside `clip`.
fn along(pts: &[(f64, f64)], every: f64, offset: f64, clip: &PxRect) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut next = offset.rem_euclid(every);
    let mut s = 0.0;
    for w in pts.windows(2) {
        let Some((a, b)) = super::raster::clip_segment(w[0], w[1], &clip.grow(2.0)) else {
            continue;
        };
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        if !(len.is_finite() && len > 0.0) {
            continue;
        }
        while next <= s + len {
            let t = (next - s) / len;
            out.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
            next += every;
            if out.len() > 100_000 {
                return out;
            }
        }
        s += len;
    }
    out
}

/// Draws the inset of `p` into `r`.
fn draw_inset(canvas: &mut Canvas, r: PxRect, p: &Prep, inset: &Inset) {
    let (a, b) = inset.x_range;
    let xa = Axis {
        scale: inset.x_scale.unwrap_or(p.x_axis.scale),
        range: Some((a, b)),
        margin: 0.0,
        ..p.x_axis.clone()
    };
    let ya = Axis {
        scale: inset.y_scale.unwrap_or(p.y_axis.scale),
        range: None,
        ..p.y_axis.clone()
    };
    let src = Source {
        title: &inset.title,
        labels: &[],
        legend: LegendMode::Hidden,
        equal_aspect: false,
        inset: None,
        coincide: None,
        ..p.src
    };
    let sub = prepare(
        src,
        xa,
        ya,
        Some((a, b)),
        Some((p.styles.clone(), p.colours.clone())),
    );
    canvas.fill_rect(r, Rgb::WHITE, 1.0);
    draw_panel(
        canvas,
        PxRect::new(r.x0 + 2.0, r.y0 + 2.0, r.x1 - 4.0, r.y1 - 2.0),
        &sub,
        &COMPACT,
        true,
        0.0,
    );
    canvas.frame(r, Rgb(150, 150, 150));
}

impl Panel {
    /// The groups of coinciding curves that this panel's legend names when drawn (the same detection).
    pub fn coinciding(&self) -> Vec<super::CoincideGroup> {
        prepare(
            self.into(),
            self.x_axis.clone(),
            self.y_axis.clone(),
            None,
            None,
        )
        .groups
    }

    /// A panel of the differences between the members of `group` and its first member, interpolated onto the
    /// first member's x: relative, `(yᵢ − y₀)/|y₀|`, for a log y axis; in the y axis' unit for a linear one.
    /// Members keep their colours; draw it under the panel to show *how* equal coinciding curves are.
    pub fn difference_panel(&self, group: &super::CoincideGroup) -> Panel {
        let prep = prepare(
            self.into(),
            self.x_axis.clone(),
            self.y_axis.clone(),
            None,
            None,
        );
        let relative = self.y_axis.scale == Scale::Log;
        let Some(&first) = group.members.first() else {
            return Panel::new(self.x_axis.clone(), Axis::linear("difference", ""));
        };
        let base = &self.curves[first];
        let n0 = n_points(base);
        let y_axis = if relative {
            Axis::linear(format!("relative difference to {}", base.label), "")
        } else {
            Axis::linear(
                format!("difference to {}", base.label),
                self.y_axis.unit.clone(),
            )
        };
        let mut p = Panel::new(self.x_axis.clone(), y_axis);
        p.coincide_tolerance = None;
        for &i in &group.members[1..] {
            let c = &self.curves[i];
            let n = n_points(c);
            let d: Vec<f64> = (0..n0)
                .map(|k| {
                    let (x, y0) = (base.x[k], base.y[k]);
                    match coincide::interp(&c.x[..n], &c.y[..n], x) {
                        Some(y) if relative => (y - y0) / y0.abs(),
                        Some(y) => y - y0,
                        None => f64::NAN,
                    }
                })
                .collect();
            p.curves.push(
                Curve::new(c.label.clone(), base.x[..n0].to_vec(), d)
                    .with_style(Style::line().colour(prep.colours[i]).width(1.2)),
            );
        }
        p
    }
}
