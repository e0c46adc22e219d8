//! Text: the bundled DejaVu Sans, laid out with the font's own advances and kerning, with a small markup for
//! sub- and superscripts and proper placement of combining marks.
//!
//! # Why not plotters' text
//! plotters 0.3.7 draws `ab_glyph` text (`style/font/ab_glyph.rs`, `FontDataInternal::draw`) by placing each
//! glyph's rasterised box at the *truncated* pen position and discarding the box's left edge
//! (`px_bounds().min.x`), i.e. the integer part of the glyph's left side bearing. Glyphs whose side bearing
//! rounds down to one pixel or more ("m", "n", "i", "r" at 15–17 px) are drawn one pixel too far left, and the
//! glyph after them one pixel too far right: "landm arks", "tim e", "form ation". Combining marks (x̂ = x + U+0302)
//! have zero advance and an outline left of the origin; dropping the box offset puts the hat *after* the x.
//! Here every glyph is positioned with [`ab_glyph::Glyph::position`] (sub-pixel pen position, side bearing kept),
//! so the rendered width is the sum of advances plus kerning.
//!
//! # Markup
//! `_{…}` is a subscript and `^{…}` a superscript (braces required, so `est_error` stays literal):
//! `"x̂_{k|k}"`, `"σ^{2}_{prior}"`. Unicode super/subscript characters (`10⁻²`, `ε²`) work as well.
//! A brace group without its closing brace is literal text.

use std::sync::LazyLock;

use ab_glyph::{point, Font, FontRef, Glyph, PxScale, ScaleFont};

static FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The bundled DejaVu Sans (a valid font checked by a unit test, so parsing cannot fail).
static FONT: LazyLock<FontRef<'static>> =
    LazyLock::new(|| FontRef::try_from_slice(FONT_BYTES).expect("the bundled DejaVu Sans parses"));

/// Scale of sub- and superscripts relative to the surrounding text.
const SCRIPT_SCALE: f32 = 0.72;
/// Baseline shift of a subscript, in units of the surrounding font size (downwards).
const SUB_SHIFT: f32 = 0.20;
/// Baseline shift of a superscript, in units of the surrounding font size (upwards).
const SUPER_SHIFT: f32 = 0.36;
/// Gap between a base glyph's ink and a combining mark above it, in units of the font size.
const MARK_GAP: f32 = 0.05;
/// Cap height of DejaVu Sans as a fraction of the pixel size (1493 / 2384 font units).
const CAP_HEIGHT: f32 = 0.626;

/// The font's raw bytes (for plotters' font registration and for tests).
pub fn font_bytes() -> &'static [u8] {
    FONT_BYTES
}

/// Vertical level of a run of text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Normal text.
    Base,
    /// Subscript: smaller and lowered.
    Sub,
    /// Superscript: smaller and raised.
    Super,
}

/// Splits marked-up text into characters with their level (see the module docs for the markup).
pub fn parse(text: &str) -> Vec<(char, Level)> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::with_capacity(chars.len());
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if (c == '_' || c == '^') && chars.get(i + 1) == Some(&'{') {
            // Find the matching close brace (nested braces are kept as text).
            let mut depth = 0usize;
            let mut end = None;
            for (j, &d) in chars.iter().enumerate().skip(i + 1) {
                match d {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            end = Some(j);
                            break;
                        }
                    }
                    _ => {}
                }
            }
            if let Some(end) = end {
                let level = if c == '_' { Level::Sub } else { Level::Super };
                out.extend(chars[i + 2..end].iter().map(|&d| (d, level)));
                i = end + 1;
                continue;
            }
        }
        out.push((c, Level::Base));
        i += 1;
    }
    out
}

/// The text without markup (what a screen reader or a CSV would show).
pub fn plain(text: &str) -> String {
    parse(text).into_iter().map(|(c, _)| c).collect()
}

/// Whether `c` is a combining mark drawn over the previous glyph.
fn is_combining(c: char) -> bool {
    matches!(c as u32, 0x0300..=0x036F | 0x1AB0..=0x1AFF | 0x1DC0..=0x1DFF | 0x20D0..=0x20FF | 0xFE20..=0xFE2F)
}

/// Characters of `text` that the bundled font has no glyph for (they would render as a box).
pub fn missing_glyphs(text: &str) -> Vec<char> {
    let mut v: Vec<char> = parse(text)
        .into_iter()
        .map(|(c, _)| c)
        .filter(|&c| !c.is_control() && FONT.glyph_id(c).0 == 0)
        .collect();
    v.dedup();
    v
}

/// Extent of laid-out text, in pixels, relative to the start of its baseline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    /// Advance width (sum of advances and kerning).
    pub width: f32,
    /// Height above the baseline (positive).
    pub ascent: f32,
    /// Depth below the baseline (positive).
    pub descent: f32,
}

impl Extent {
    /// Total height, `ascent + descent`.
    pub fn height(&self) -> f32 {
        self.ascent + self.descent
    }
}

/// Glyphs positioned relative to the start of the baseline (y grows downwards).
#[derive(Clone, Debug)]
pub struct Layout {
    glyphs: Vec<Glyph>,
    /// The extent of the text.
    pub extent: Extent,
}

/// Lays out marked-up `text` at pixel size `size` (the font's ascent − descent, as `ab_glyph::PxScale`).
pub fn layout(text: &str, size: f32) -> Layout {
    let size = if size.is_finite() && size > 0.0 {
        size
    } else {
        1.0
    };
    let font = &*FONT;
    let base = font.as_scaled(PxScale::from(size));
    let mut glyphs: Vec<Glyph> = Vec::new();
    let mut pen = 0f32;
    let (mut ascent, mut descent) = (base.ascent(), -base.descent());
    // The previous spacing glyph (id, level) for kerning, and the index of the last base glyph with its mark top.
    let mut prev: Option<(ab_glyph::GlyphId, Level)> = None;
    let mut last_base: Option<(usize, f32)> = None;
    // A subscript right after a superscript (or the reverse) is stacked under it, as in σ^{2}_{prior}:
    // `script` holds the start and end of the current script runs and whether they are stacked already.
    let mut script: Option<(f32, f32, bool)> = None;
    let mut level_before = Level::Base;
    for (c, level) in parse(text) {
        if level != level_before && !is_combining(c) {
            if level == Level::Base {
                if let Some((_, end, _)) = script.take() {
                    pen = pen.max(end);
                }
            } else if level_before == Level::Base {
                script = Some((pen, pen, false));
            } else if let Some((start, end, false)) = script {
                // The other script right after the first: stack it.
                pen = start;
                prev = None;
                script = Some((start, end, true));
            } else if let Some((_, end, true)) = script {
                pen = pen.max(end);
                script = Some((pen, pen, false));
            }
        }
        level_before = level;
        let (scale, shift) = match level {
            Level::Base => (size, 0.0),
            Level::Sub => (size * SCRIPT_SCALE, SUB_SHIFT * size),
            Level::Super => (size * SCRIPT_SCALE, -SUPER_SHIFT * size),
        };
        let sf = font.as_scaled(PxScale::from(scale));
        let id = sf.glyph_id(c);
        if is_combining(c) {
            if let Some((bi, top)) = last_base {
                let b = &glyphs[bi];
                let bsf = font.as_scaled(b.scale);
                let (bx0, bx1, btop) = match font.outline(b.id) {
                    Some(o) => (
                        b.position.x + o.bounds.min.x * bsf.h_scale_factor(),
                        b.position.x + o.bounds.max.x * bsf.h_scale_factor(),
                        b.position.y - o.bounds.min.y * bsf.v_scale_factor(),
                    ),
                    None => (
                        b.position.x,
                        b.position.x + bsf.h_advance(b.id),
                        b.position.y,
                    ),
                };
                let btop = btop.min(top);
                let mut g = id.with_scale_and_position(b.scale, point(0.0, b.position.y));
                if let Some(o) = font.outline(id) {
                    let msf = font.as_scaled(b.scale);
                    let (mx0, mx1) = (
                        o.bounds.min.x * msf.h_scale_factor(),
                        o.bounds.max.x * msf.h_scale_factor(),
                    );
                    let mbottom = b.position.y - o.bounds.max.y * msf.v_scale_factor();
                    let mtop = b.position.y - o.bounds.min.y * msf.v_scale_factor();
                    g.position.x = (bx0 + bx1) / 2.0 - (mx0 + mx1) / 2.0;
                    // Raise the mark so that it clears the base glyph's ink (capitals, ascenders).
                    let want_bottom = btop - MARK_GAP * b.scale.y;
                    let lift = (mbottom - want_bottom).max(0.0);
                    g.position.y -= lift;
                    let new_top = mtop - lift;
                    ascent = ascent.max(-new_top);
                    last_base = Some((bi, new_top - MARK_GAP * b.scale.y));
                }
                glyphs.push(g);
                continue;
            }
        }
        if let Some((pid, plevel)) = prev {
            if plevel == level {
                pen += sf.kern(pid, id);
            }
        }
        glyphs.push(id.with_scale_and_position(PxScale::from(scale), point(pen, shift)));
        last_base = Some((glyphs.len() - 1, f32::INFINITY));
        pen += sf.h_advance(id);
        if let Some(s) = script.as_mut() {
            s.1 = s.1.max(pen);
        }
        prev = Some((id, level));
        ascent = ascent.max(sf.ascent() - shift);
        descent = descent.max(-sf.descent() + shift);
    }
    if let Some((_, end, _)) = script {
        pen = pen.max(end);
    }
    Layout {
        glyphs,
        extent: Extent {
            width: pen,
            ascent,
            descent,
        },
    }
}

/// Extent of marked-up `text` at `size` without drawing it.
pub fn measure(text: &str, size: f32) -> Extent {
    layout(text, size).extent
}

/// Horizontal anchor of a text position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HAlign {
    /// The position is the left end of the text.
    Left,
    /// The position is the horizontal centre.
    Center,
    /// The position is the right end.
    Right,
}

/// Vertical anchor of a text position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VAlign {
    /// The position is the top of the text's ascent.
    Top,
    /// The position is half a cap height above the baseline (numbers and capitals look centred).
    Middle,
    /// The position is on the baseline.
    Baseline,
    /// The position is the bottom of the text's descent.
    Bottom,
}

/// Direction of the baseline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rotation {
    /// Left to right.
    None,
    /// Bottom to top (a y-axis label): rotated 90° counter-clockwise.
    Up,
}

impl Layout {
    /// Calls `f(x, y, coverage)` for every pixel of the text whose anchor point (`h`, `v`) is at `(x, y)`.
    pub fn rasterise(
        &self,
        at: (f32, f32),
        h: HAlign,
        v: VAlign,
        rot: Rotation,
        mut f: impl FnMut(i32, i32, f32),
    ) {
        let e = self.extent;
        let dx = match h {
            HAlign::Left => 0.0,
            HAlign::Center => -e.width / 2.0,
            HAlign::Right => -e.width,
        };
        let size = self.glyphs.first().map_or(12.0, |g| g.scale.y);
        let dy = match v {
            VAlign::Top => e.ascent,
            VAlign::Middle => CAP_HEIGHT * size / 2.0,
            VAlign::Baseline => 0.0,
            VAlign::Bottom => -e.descent,
        };
        // Lay out in local coordinates (origin at the anchor, baseline at dy), then rotate about the anchor.
        // Local sub-pixel offsets are kept for unrotated text; rotated text is laid out on whole pixels.
        let (ox, oy) = match rot {
            Rotation::None => (at.0 + dx, at.1 + dy),
            Rotation::Up => (dx, dy),
        };
        for g in &self.glyphs {
            let mut g = g.clone();
            g.position = point(g.position.x + ox, g.position.y + oy);
            if let Some(q) = FONT.outline_glyph(g) {
                let b = q.px_bounds();
                let (bx, by) = (b.min.x as i32, b.min.y as i32);
                q.draw(|x, y, c| {
                    let (lx, ly) = (bx + x as i32, by + y as i32);
                    match rot {
                        Rotation::None => f(lx, ly, c),
                        Rotation::Up => {
                            f(at.0.round() as i32 + ly, at.1.round() as i32 - lx - 1, c)
                        }
                    }
                });
            }
        }
    }

    /// The pixel box `(x0, y0, x1, y1)` the text covers when anchored as in [`Layout::rasterise`].
    pub fn bounds(
        &self,
        at: (f32, f32),
        h: HAlign,
        v: VAlign,
        rot: Rotation,
    ) -> (f32, f32, f32, f32) {
        let e = self.extent;
        let x0 = match h {
            HAlign::Left => 0.0,
            HAlign::Center => -e.width / 2.0,
            HAlign::Right => -e.width,
        };
        let size = self.glyphs.first().map_or(12.0, |g| g.scale.y);
        let base = match v {
            VAlign::Top => e.ascent,
            VAlign::Middle => CAP_HEIGHT * size / 2.0,
            VAlign::Baseline => 0.0,
            VAlign::Bottom => -e.descent,
        };
        let (lx0, ly0, lx1, ly1) = (x0, base - e.ascent, x0 + e.width, base + e.descent);
        match rot {
            Rotation::None => (at.0 + lx0, at.1 + ly0, at.0 + lx1, at.1 + ly1),
            Rotation::Up => (at.0 + ly0, at.1 - lx1, at.0 + ly1, at.1 - lx0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_font_parses_and_covers_the_symbols_we_use() {
        assert!(FontRef::try_from_slice(FONT_BYTES).is_ok());
        let used = "ε_{k} x̂_{k|k} σ² λ ‖·‖ − ± ≈ ≡ … 10⁻²³⁴⁵⁶⁷⁸⁹⁰¹ μ Δ τ ∞ · ⁺ û ○ ▲ ◆ θ Θ ψ";
        assert_eq!(missing_glyphs(used), Vec::<char>::new());
    }

    #[test]
    fn markup_needs_braces() {
        assert_eq!(plain("x̂_{k|k}"), "x̂k|k");
        assert_eq!(plain("est_error"), "est_error");
        assert_eq!(plain("a_{open"), "a_{open");
        let p = parse("σ^{2}_{p}");
        assert_eq!(p[1], ('2', Level::Super));
        assert_eq!(p[2], ('p', Level::Sub));
    }

    #[test]
    fn width_is_the_sum_of_advances_and_kerning() {
        let font = FONT.as_scaled(PxScale::from(15.0));
        let m = font.h_advance(font.glyph_id('m'));
        let w = measure("mmmm", 15.0).width;
        let kern = font.kern(font.glyph_id('m'), font.glyph_id('m'));
        assert!(
            (w - 4.0 * m - 3.0 * kern).abs() < 1e-3,
            "{w} vs {}",
            4.0 * m
        );
    }

    #[test]
    fn a_subscript_after_a_superscript_is_stacked() {
        let stacked = measure("σ^{2}_{prior}", 20.0).width;
        let both = measure("σ^{2}", 20.0)
            .width
            .max(measure("σ_{prior}", 20.0).width);
        assert!((stacked - both).abs() < 1e-3, "{stacked} vs {both}");
        // Base text after the stack starts after the longer script.
        let after = measure("σ^{2}_{prior}x", 20.0).width;
        assert!((after - both - measure("x", 20.0).width).abs() < 0.5);
    }

    #[test]
    fn combining_hat_sits_over_its_base() {
        // The hat of x̂ is horizontally centred on the x's ink, within half a pixel.
        let l = layout("x\u{302}", 40.0);
        assert_eq!(l.glyphs.len(), 2);
        let font = &*FONT;
        let centre = |g: &Glyph| {
            let q = font.outline_glyph(g.clone()).expect("outline");
            let b = q.px_bounds();
            ((b.min.x + b.max.x) / 2.0, b.min.y, b.max.y)
        };
        let (xc, xtop, _) = centre(&l.glyphs[0]);
        let (hc, _, hbottom) = centre(&l.glyphs[1]);
        assert!((xc - hc).abs() <= 1.0, "x centre {xc}, hat centre {hc}");
        assert!(
            hbottom <= xtop + 0.5,
            "hat bottom {hbottom} below x top {xtop}"
        );
        // Width unchanged by the mark.
        assert!((l.extent.width - measure("x", 40.0).width).abs() < 1e-4);
    }
}
