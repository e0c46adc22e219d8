//! A figure toolkit for every figure of edgekf: line plots with ±1σ bands, paths, markers, insets — drawn
//! whatever the data, in bounded time, and typeset properly.
//!
//! The toolkit is data-agnostic (plain slices and `Vec`s in, a PNG and a [`RenderReport`] out) and does all its
//! own drawing: plotters only encodes the PNG. That is deliberate:
//! - **No hang, no panic** ([`range`], [`ticks`]): plotters' `compute_f64_key_points` spins forever on some huge
//!   ranges and panics on others; here ticks are computed by bounded loops on sanitised ranges, coordinates are
//!   clipped in `f64` before they become pixels, non-finite values are left out and counted.
//! - **Typesetting** ([`text`]): the bundled DejaVu Sans laid out with its own advances and kerning (plotters'
//!   `ab_glyph` layout puts a gap after every "m"), `_{…}`/`^{…}` markup, combining marks centred on their base.
//! - **Reading** ([`legend`], [`coincide`], [`palette`]): ticks `10⁻²`, legends placed where they cover no data,
//!   curves that coincide drawn distinguishably and said so, log-time axes and insets for transients, a
//!   translucent band under a thin mean line, colour-blind-safe colours.
//!
//! # Example
//! ```
//! use edgekf_figure::{Axis, Curve, Figure, Panel, Style};
//!
//! let t: Vec<f64> = (1..=3000).map(|k| f64::from(k) * 1e-2).collect();
//! let mean: Vec<f64> = t.iter().map(|t| 0.1 + (-t).exp()).collect();
//! let lower: Vec<f64> = mean.iter().map(|m| 0.8 * m).collect();
//! let upper: Vec<f64> = mean.iter().map(|m| 1.2 * m).collect();
//! let panel = Panel::new(Axis::log("time t", "s").tight(), Axis::log("estimation error ε_{k}", "m"))
//!     .with_curve(Curve::new("rkf", t.clone(), mean).with_band(lower, upper))
//!     .with_curve(Curve::new("mle", t, vec![0.3; 3000]).with_style(Style::line().dashed()));
//! let (canvas, report) = Figure::single("Estimation error (mean ± 1σ over 50 runs)", panel).draw();
//! assert_eq!(canvas.width(), 1100);
//! assert!(report.warnings().is_empty());
//! ```
//!
//! Call [`Figure::render`] to write a PNG; [`RenderReport::warnings`] lists what a reader should know (values
//! left out, clamped ranges, a log floor), and the figure shows the same as a note under the plot.

#![warn(missing_docs)]

pub mod backend;
pub mod coincide;
pub mod legend;
pub mod palette;
pub mod plot;
pub mod plot_garkf;
pub mod range;
pub mod raster;
mod render;
pub mod text;
pub mod ticks;

use std::path::{Path, PathBuf};

pub use coincide::CoincideGroup;
pub use legend::Placement;
pub use range::{AxisReport, FloorRule};
pub use raster::{Canvas, PxRect, Rgb, Shape};
pub use text::{HAlign, VAlign};
pub use ticks::Tick;

/// Draws the figures of a study — every plot of the scenario, or those whose file stem is in
/// `only` — each to `path_of("STEM.png")` (the CLI and the Python package stage them in a
/// temporary directory). GA-RKF panels, sweep summaries and the indicator figure go to
/// [`plot_garkf`] (with `extra`: a sweep's results, a companion run), the rest to [`plot`]; the
/// figures are drawn in parallel on the caller's rayon pool.
///
/// # Errors
/// [`StudyFigureError`] when a figure cannot be written, or a GA-RKF figure lacks the data it
/// needs.
pub fn render_study(
    mut path_of: impl FnMut(&str) -> PathBuf,
    sc: &edgekf::scenario::Scenario,
    res: &edgekf::sim::Results,
    only: Option<&[&str]>,
    extra: &plot_garkf::Extra<'_>,
) -> Result<(), StudyFigureError> {
    use rayon::prelude::*;
    let wanted: Vec<_> = sc
        .plots()
        .iter()
        .filter(|p| only.is_none_or(|want| want.contains(&p.file())))
        .map(|p| (p, path_of(&format!("{}.png", p.file()))))
        .collect();
    // Each figure is drawn and encoded by itself, so they are drawn in parallel (on the
    // caller's rayon pool); the first error in the scenario's order is the one returned.
    let drawn: Vec<Result<(), StudyFigureError>> = wanted
        .par_iter()
        .map(|(p, path)| {
            if plot_garkf::handles(p) {
                plot_garkf::render(path, p, sc, res, extra)
            } else {
                plot::render(path, p, sc, res)
            }
        })
        .collect();
    drawn.into_iter().collect()
}

/// Errors of writing a figure.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// The PNG could not be encoded or written.
    #[error("cannot write the figure: {0}")]
    Encode(String),
    /// A directory or file operation failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path involved.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Why a figure of a study could not be drawn ([`render_study`], [`plot::render`],
/// [`plot_garkf::render`]).
#[derive(Debug, thiserror::Error)]
pub enum StudyFigureError {
    /// A figure of [`plot`] could not be written.
    #[error("cannot draw {}", path.display())]
    Draw {
        /// The PNG.
        path: PathBuf,
        /// Why.
        source: FigureError,
    },
    /// A figure of [`plot_garkf`] could not be written.
    #[error(transparent)]
    Write(#[from] FigureError),
    /// [`plot_garkf::render`] was given a figure that is not one of its own.
    #[error("{0} is not a GA-RKF figure")]
    NotGarkf(String),
    /// A panel figure draws the sweep's values (`columns` or `series` = `"points"`), but there
    /// are no sweep results.
    #[error("this figure draws the sweep's values, but there is no sweep")]
    NoSweep,
    /// A summary figure without the sweep's results.
    #[error("a summary figure needs the sweep's results")]
    SummaryWithoutSweep,
    /// The indicator figure names an estimator the scenario does not have.
    #[error("no estimator `{0}`")]
    NoEstimator(String),
    /// The indicator figure's bound is undefined: no agent has a feasible RAL.
    #[error("no agent has a feasible RAL on the nominal graph")]
    NoFeasibleRal,
    /// The indicator figure's estimator reports no ψ or δ.
    #[error("`{0}` reports no ψ or δ")]
    NoPsiOrDelta(String),
}

/// Axis scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scale {
    /// Linear.
    Linear,
    /// Base-10 logarithmic; values ≤ 0 are left out (and counted).
    Log,
}

/// One axis: its label, unit, scale and (optionally) a fixed range.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// The quantity, with markup (`"estimation error ε_{k}"`).
    pub label: String,
    /// The unit (`"m"`, `"s"`, `"m²"`); empty for a dimensionless quantity. Shown as "label (unit)".
    pub unit: String,
    /// Linear or log.
    pub scale: Scale,
    /// A fixed range; `None` (the default) fits the data. An unusable range (empty, non-finite, ≤ 0 on a log
    /// axis) is replaced by the data's range and reported.
    pub range: Option<(f64, f64)>,
    /// Space added beyond the data on each side, as a share of the span (of log10 values on a log axis).
    pub margin: f64,
}

impl Axis {
    /// A linear axis with a 3 % margin.
    pub fn linear(label: impl Into<String>, unit: impl Into<String>) -> Self {
        Axis {
            label: label.into(),
            unit: unit.into(),
            scale: Scale::Linear,
            range: None,
            margin: 0.03,
        }
    }
    /// A log axis with a 3 % margin.
    pub fn log(label: impl Into<String>, unit: impl Into<String>) -> Self {
        Axis {
            scale: Scale::Log,
            ..Axis::linear(label, unit)
        }
    }
    /// No margin: the data touch both ends (time axes).
    pub fn tight(mut self) -> Self {
        self.margin = 0.0;
        self
    }
    /// A fixed range.
    pub fn with_range(mut self, lo: f64, hi: f64) -> Self {
        self.range = Some((lo, hi));
        self
    }
    /// "label (unit)", or the label alone when there is no unit.
    pub fn title(&self) -> String {
        match (self.label.is_empty(), self.unit.is_empty()) {
            (_, true) => self.label.clone(),
            (true, false) => format!("({})", self.unit),
            (false, false) => format!("{} ({})", self.label, self.unit),
        }
    }
}

/// Line dash patterns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dash {
    /// ────
    Solid,
    /// ─ ─ ─
    Dashed,
    /// ·····
    Dotted,
    /// ─·─·
    DashDot,
    /// ── ──
    LongDash,
}

impl Dash {
    /// All patterns, in the order coinciding curves get them.
    pub const ALL: [Dash; 5] = [
        Dash::Solid,
        Dash::Dashed,
        Dash::Dotted,
        Dash::DashDot,
        Dash::LongDash,
    ];

    /// On/off lengths in pixels for a line of `width` pixels, `None` for solid.
    pub fn pattern(self, width: f64) -> Option<Vec<f64>> {
        let k = (width / 1.5).max(1.0);
        let p: &[f64] = match self {
            Dash::Solid => return None,
            Dash::Dashed => &[7.0, 4.5],
            Dash::Dotted => &[1.2, 3.3],
            Dash::DashDot => &[8.0, 3.5, 1.2, 3.5],
            Dash::LongDash => &[14.0, 5.0],
        };
        Some(p.iter().map(|v| v * k).collect())
    }
}

/// A marker drawn at points of a curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Marker {
    /// Shape.
    pub shape: Shape,
    /// Diameter in pixels.
    pub size: f64,
    /// Filled, or outlined.
    pub filled: bool,
    /// `None`: at every data point (a scatter); `Some(d)`: every `d` pixels along the drawn line (to tell lines
    /// apart without hiding them).
    pub every: Option<f64>,
    /// Where along the line the first marker sits, in pixels (staggers the markers of coinciding curves).
    pub offset: f64,
}

impl Marker {
    /// A filled marker of `size` pixels at every data point.
    pub fn new(shape: Shape, size: f64) -> Self {
        Marker {
            shape,
            size,
            filled: true,
            every: None,
            offset: 0.0,
        }
    }
    /// Outlined instead of filled.
    pub fn hollow(mut self) -> Self {
        self.filled = false;
        self
    }
    /// One marker every `px` pixels along the line, the first at `offset`.
    pub fn spaced(mut self, px: f64, offset: f64) -> Self {
        self.every = Some(px);
        self.offset = offset;
        self
    }
}

/// How a curve is drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct Style {
    /// Colour; `None` takes the next colour of [`palette::series`].
    pub colour: Option<Rgb>,
    /// Line width in pixels (1.5 by default: thin enough for 3,000 noisy points).
    pub width: f64,
    /// Dash pattern; `None` draws no line (markers only).
    pub dash: Option<Dash>,
    /// Markers.
    pub marker: Option<Marker>,
    /// Opacity of the band (0.18 by default).
    pub band_opacity: f32,
}

impl Default for Style {
    fn default() -> Self {
        Style {
            colour: None,
            width: 1.5,
            dash: Some(Dash::Solid),
            marker: None,
            band_opacity: 0.18,
        }
    }
}

impl Style {
    /// A solid line in the next palette colour.
    pub fn line() -> Self {
        Style::default()
    }
    /// Markers only, no line.
    pub fn markers(marker: Marker) -> Self {
        Style {
            dash: None,
            marker: Some(marker),
            ..Style::default()
        }
    }
    /// With this colour.
    pub fn colour(mut self, c: Rgb) -> Self {
        self.colour = Some(c);
        self
    }
    /// With this line width.
    pub fn width(mut self, w: f64) -> Self {
        self.width = w;
        self
    }
    /// Dashed.
    pub fn dashed(self) -> Self {
        self.dash(Dash::Dashed)
    }
    /// With this dash pattern.
    pub fn dash(mut self, d: Dash) -> Self {
        self.dash = Some(d);
        self
    }
    /// With markers.
    pub fn marker(mut self, m: Marker) -> Self {
        self.marker = Some(m);
        self
    }
}

/// One curve: points `(x[i], y[i])`, optionally a band `lower[i] ≤ … ≤ upper[i]` (e.g. mean ± 1σ).
///
/// Lengths may differ (the shortest wins); non-finite values are left out (the line breaks there) and counted.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    /// Legend label with markup; empty: not in the legend. Curves with equal labels share one entry.
    pub label: String,
    /// x values.
    pub x: Vec<f64>,
    /// y values (the mean, for a band).
    pub y: Vec<f64>,
    /// `(lower, upper)` band edges.
    pub band: Option<(Vec<f64>, Vec<f64>)>,
    /// Style.
    pub style: Style,
}

impl Curve {
    /// A solid line in the next palette colour.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Curve {
            label: label.into(),
            x,
            y,
            band: None,
            style: Style::default(),
        }
    }
    /// With a band between `lower` and `upper`.
    pub fn with_band(mut self, lower: Vec<f64>, upper: Vec<f64>) -> Self {
        self.band = Some((lower, upper));
        self
    }
    /// With this style.
    pub fn with_style(mut self, s: Style) -> Self {
        self.style = s;
        self
    }
}

/// A shaded x interval (e.g. a disturbance window), behind the curves.
#[derive(Clone, Debug, PartialEq)]
pub struct Shade {
    /// Start.
    pub from: f64,
    /// End.
    pub to: f64,
    /// Legend label; empty: none.
    pub label: String,
    /// Colour.
    pub colour: Rgb,
}

/// A text label at a data point (e.g. "m0" next to a landmark, a link weight), drawn over the curves with a
/// white halo so that lines under it do not cross the letters.
#[derive(Clone, Debug, PartialEq)]
pub struct Label {
    /// Data x.
    pub x: f64,
    /// Data y.
    pub y: f64,
    /// Text with markup.
    pub text: String,
    /// Offset from the point in pixels (y down).
    pub offset: (f64, f64),
    /// Horizontal anchor.
    pub h: HAlign,
    /// Vertical anchor.
    pub v: VAlign,
    /// Size in pixels.
    pub size: f32,
    /// Colour.
    pub colour: Rgb,
}

impl Label {
    /// A 14-pixel black label centred above the point.
    pub fn new(x: f64, y: f64, text: impl Into<String>) -> Self {
        Label {
            x,
            y,
            text: text.into(),
            offset: (0.0, -6.0),
            h: HAlign::Center,
            v: VAlign::Bottom,
            size: 14.0,
            colour: Rgb::BLACK,
        }
    }
}

/// Where the legend goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LegendMode {
    /// Computed: inside where it covers no data, else outside on the right.
    #[default]
    Auto,
    /// Always outside on the right.
    Outside,
    /// No legend.
    Hidden,
}

/// A zoomed copy of the panel over an x interval (e.g. the first second of a 30 s run), drawn in the corner
/// where it covers the least data.
#[derive(Clone, Debug, PartialEq)]
pub struct Inset {
    /// The x interval shown.
    pub x_range: (f64, f64),
    /// x scale of the inset (default: the panel's).
    pub x_scale: Option<Scale>,
    /// y scale of the inset (default: the panel's).
    pub y_scale: Option<Scale>,
    /// Size as a share of the plot area (width, height).
    pub size: (f64, f64),
    /// A short title ("first 1 s").
    pub title: String,
}

impl Inset {
    /// An inset over `[from, to]`, 40 % × 42 % of the plot area.
    pub fn new(from: f64, to: f64, title: impl Into<String>) -> Self {
        Inset {
            x_range: (from, to),
            x_scale: None,
            y_scale: None,
            size: (0.4, 0.42),
            title: title.into(),
        }
    }
}

/// One plot area with its axes.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title over the plot area (empty: none).
    pub title: String,
    /// x axis.
    pub x_axis: Axis,
    /// y axis.
    pub y_axis: Axis,
    /// Curves, drawn in order (bands first, then lines, then markers).
    pub curves: Vec<Curve>,
    /// Shaded x intervals.
    pub shades: Vec<Shade>,
    /// Text labels at data points.
    pub labels: Vec<Label>,
    /// Legend placement.
    pub legend: LegendMode,
    /// Equal units per pixel on both axes (maps, paths).
    pub equal_aspect: bool,
    /// A zoomed inset.
    pub inset: Option<Inset>,
    /// Relative tolerance for coinciding curves (default 10⁻³); `None` turns detection off.
    pub coincide_tolerance: Option<f64>,
    /// Grid lines at the labelled ticks.
    pub grid: bool,
}

impl Panel {
    /// An empty panel with these axes.
    pub fn new(x_axis: Axis, y_axis: Axis) -> Self {
        Panel {
            title: String::new(),
            x_axis,
            y_axis,
            curves: Vec::new(),
            shades: Vec::new(),
            labels: Vec::new(),
            legend: LegendMode::Auto,
            equal_aspect: false,
            inset: None,
            coincide_tolerance: Some(1e-3),
            grid: true,
        }
    }
    /// With a title.
    pub fn with_title(mut self, t: impl Into<String>) -> Self {
        self.title = t.into();
        self
    }
    /// With one more curve.
    pub fn with_curve(mut self, c: Curve) -> Self {
        self.curves.push(c);
        self
    }
    /// With an inset.
    pub fn with_inset(mut self, i: Inset) -> Self {
        self.inset = Some(i);
        self
    }
}

/// A figure: a title, panels on a grid, notes under them.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Title at the top (empty: none).
    pub title: String,
    /// Size in pixels.
    pub size: (u32, u32),
    /// Panels, row by row.
    pub panels: Vec<Panel>,
    /// Panels per row.
    pub columns: usize,
    /// Lines of text under the panels.
    pub notes: Vec<String>,
    /// Add notes for what the reader should know (values left out, clamped, a log floor).
    pub auto_notes: bool,
}

impl Figure {
    /// An empty 1100 × 720 figure.
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            size: (1100, 720),
            panels: Vec::new(),
            columns: 1,
            notes: Vec::new(),
            auto_notes: true,
        }
    }
    /// A figure of one panel.
    pub fn single(title: impl Into<String>, panel: Panel) -> Self {
        Figure::new(title).with_panel(panel)
    }
    /// With one more panel.
    pub fn with_panel(mut self, p: Panel) -> Self {
        self.panels.push(p);
        self
    }
    /// With this size.
    pub fn with_size(mut self, w: u32, h: u32) -> Self {
        self.size = (w, h);
        self
    }
    /// With a note line.
    pub fn with_note(mut self, n: impl Into<String>) -> Self {
        self.notes.push(n.into());
        self
    }
    /// Draws the figure in memory.
    pub fn draw(&self) -> (Canvas, RenderReport) {
        render::figure(self)
    }
    /// Draws the figure and writes it as a PNG file.
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn render(&self, path: &Path) -> Result<RenderReport, FigureError> {
        let (canvas, report) = self.draw();
        canvas.save_png(path)?;
        Ok(report)
    }
}

/// What happened to one curve's data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CurveReport {
    /// The label.
    pub label: String,
    /// Points given (shortest of x and y).
    pub points: usize,
    /// Points with a non-finite x or y, left out.
    pub non_finite: usize,
    /// Points with x or y ≤ 0 on a log axis, left out (their x still spans the x axis when it is usable).
    pub non_positive: usize,
    /// Band values that are non-finite (left out), or on a log axis ≤ 0 or more than a decade
    /// below the lowest curve value (drawn to the axis bottom; the axis is not stretched for them).
    pub band_outside: usize,
    /// Vertices actually stroked after per-column thinning (same pixels, fewer vertices).
    pub vertices_drawn: usize,
}

/// Where the legend went and what it covers.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendReport {
    /// Chosen position.
    pub placement: Placement,
    /// Its box in pixels.
    pub rect: PxRect,
    /// Weighted data pixels under the box (see [`legend::LINE_WEIGHT`]).
    pub covered: u64,
}

/// What happened in one panel.
#[derive(Clone, Debug, PartialEq)]
pub struct PanelReport {
    /// Panel title.
    pub title: String,
    /// The plot area in pixels.
    pub plot: PxRect,
    /// x axis scale.
    pub x_scale: Scale,
    /// y axis scale.
    pub y_scale: Scale,
    /// x axis range and sanitising.
    pub x: AxisReport,
    /// y axis range and sanitising.
    pub y: AxisReport,
    /// x ticks.
    pub x_ticks: Vec<Tick>,
    /// y ticks.
    pub y_ticks: Vec<Tick>,
    /// Per curve.
    pub curves: Vec<CurveReport>,
    /// Coinciding curves.
    pub coinciding: Vec<CoincideGroup>,
    /// The legend, if drawn.
    pub legend: Option<LegendReport>,
    /// The inset, if drawn: its box and position.
    pub inset: Option<(Placement, PxRect)>,
    /// Every axis text drawn (tick labels, axis titles, panel title) with its pixel box, to check that none
    /// overlaps another or leaves the image.
    pub texts: Vec<(String, PxRect)>,
}

impl PanelReport {
    /// Pixel position of the data point `(x, y)` (may lie outside the plot area).
    pub fn to_px(&self, x: f64, y: f64) -> (f64, f64) {
        let m = |v: f64, s: Scale, lo: f64, hi: f64, a: f64, b: f64| match s {
            Scale::Linear => a + (v - lo) / (hi - lo) * (b - a),
            Scale::Log => a + (v.log10() - lo.log10()) / (hi.log10() - lo.log10()) * (b - a),
        };
        (
            m(
                x,
                self.x_scale,
                self.x.lo,
                self.x.hi,
                self.plot.x0,
                self.plot.x1,
            ),
            m(
                y,
                self.y_scale,
                self.y.lo,
                self.y.hi,
                self.plot.y1,
                self.plot.y0,
            ),
        )
    }

    /// Human-readable notes on what was left out, clamped or floored in this panel.
    pub fn warnings(&self) -> Vec<String> {
        self.findings().into_iter().map(|(_, s)| s).collect()
    }

    /// The notes that point at bad data rather than at a routine log axis: non-finite values, values beyond
    /// ±10³⁰⁰, no data at all, an unusable fixed range.
    pub fn problems(&self) -> Vec<String> {
        self.findings()
            .into_iter()
            .filter_map(|(bad, s)| bad.then_some(s))
            .collect()
    }

    /// `(is a problem, text)` for everything a reader should know.
    fn findings(&self) -> Vec<(bool, String)> {
        let mut w: Vec<(bool, String)> = Vec::new();
        let sum = |f: fn(&CurveReport) -> usize| self.curves.iter().map(f).sum::<usize>();
        let who = |f: fn(&CurveReport) -> usize| {
            let v: Vec<&str> = self
                .curves
                .iter()
                .filter(|c| f(c) > 0 && !c.label.is_empty())
                .map(|c| c.label.as_str())
                .collect();
            let labelled = self.curves.iter().filter(|c| !c.label.is_empty()).count();
            match v.len() {
                0 => String::new(),
                k if k == labelled && k > 2 => " (all curves)".to_string(),
                1..=3 => format!(" ({})", v.join(", ")),
                k => format!(" ({}, {} and {} more)", v[0], v[1], k - 2),
            }
        };
        let n = sum(|c| c.non_finite);
        if n > 0 {
            let msg = format!(
                "{n} non-finite value{} left out{}",
                plural(n),
                who(|c| c.non_finite)
            );
            w.push((true, msg));
        }
        let n = sum(|c| c.non_positive);
        if n > 0 {
            let msg = format!(
                "{n} value{} ≤ 0 left out of the log axis{}",
                plural(n),
                who(|c| c.non_positive)
            );
            w.push((false, msg));
        }
        for (name, a) in [("x", &self.x), ("y", &self.y)] {
            if a.clamped > 0 {
                w.push((
                    true,
                    format!(
                        "{} {name} value{} beyond ±10³⁰⁰ (or 10⁻³⁰⁰ on a log axis) lie outside the axis",
                        a.clamped,
                        plural(a.clamped)
                    ),
                ));
            }
            if let Some((f, rule)) = a.floor {
                let (n, s) = (a.below_floor, plural(a.below_floor));
                let msg = match rule {
                    FloorRule::Strays => format!(
                        "{n} stray {name} value{s}, more than {} decades below all others, fall{} below the \
                         axis (it starts at {})",
                        range::GAP_DECADES,
                        if n == 1 { "s" } else { "" },
                        short(f)
                    ),
                    FloorRule::DynamicRange => format!(
                        "the {name} axis spans at most {} decades below its largest value: {n} smaller \
                         value{s} fall{} below it (it starts at {})",
                        range::MAX_DECADES,
                        if n == 1 { "s" } else { "" },
                        short(f)
                    ),
                };
                w.push((false, msg));
            }
            if let Some(c) = a.ceiling {
                let (n, s) = (a.above_ceiling, plural(a.above_ceiling));
                let msg = format!(
                    "{n} stray {name} value{s}, more than {} decades above all others, lie{} above the axis \
                     (it ends at {})",
                    range::GAP_DECADES,
                    if n == 1 { "s" } else { "" },
                    short(c)
                );
                w.push((true, msg));
            }
            if a.empty && !self.curves.is_empty() {
                w.push((true, format!("no finite {name} data to plot")));
            }
            if a.fixed_ignored {
                let msg =
                    format!("the fixed {name} range was unusable and was replaced by the data's");
                w.push((true, msg));
            }
        }
        w
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// A short number for notes: 3 significant digits, m·10ⁿ when large or small.
fn short(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor() as i32;
    if (-3..6).contains(&e) {
        let d = (2 - e).max(0) as usize;
        format!("{v:.d$}")
    } else {
        ticks::sci_label(v, 2)
    }
}

/// What happened in a figure.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderReport {
    /// Size in pixels.
    pub size: (u32, u32),
    /// Per panel.
    pub panels: Vec<PanelReport>,
}

impl RenderReport {
    /// What a reader should know, one line each, prefixed by the panel title when there are several panels.
    pub fn warnings(&self) -> Vec<String> {
        self.collect(PanelReport::warnings)
    }

    /// Only the notes about bad data (see [`PanelReport::problems`]): what a program should log.
    pub fn problems(&self) -> Vec<String> {
        self.collect(PanelReport::problems)
    }

    fn collect(&self, f: fn(&PanelReport) -> Vec<String>) -> Vec<String> {
        let many = self.panels.len() > 1;
        self.panels
            .iter()
            .flat_map(|p| {
                f(p).into_iter().map(move |w| {
                    if many && !p.title.is_empty() {
                        format!("{}: {w}", text::plain(&p.title))
                    } else {
                        w
                    }
                })
            })
            .collect()
    }
}
