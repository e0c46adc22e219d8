//! [`KernedText`]: a plotters backend wrapper whose text is laid out by [`super::text`] (correct side bearings,
//! advances and kerning, combining marks, `_{…}`/`^{…}` markup) instead of plotters' `ab_glyph` code, which puts
//! a gap after every "m". For figures still drawn with plotters' charts: wrap the backend once,
//!
//! ```no_run
//! use plotters::prelude::*;
//! use edgekf_figure::backend::KernedText;
//!
//! let root = KernedText::new(BitMapBackend::new("out.png", (800, 600))).into_drawing_area();
//! root.fill(&WHITE).unwrap();
//! root.draw(&Text::new("landmarks, time, formation", (20, 20), ("sans-serif", 16).into_font())).unwrap();
//! root.present().unwrap();
//! ```
//!
//! and every caption, label and legend text of that chart is typeset here (any font family maps to the
//! bundled DejaVu Sans; size, colour, anchor and the four rotations are honoured).

use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::FontTransform;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};

use super::text;

/// A plotters backend that draws text with [`super::text`].
pub struct KernedText<B: DrawingBackend> {
    inner: B,
}

impl<B: DrawingBackend> KernedText<B> {
    /// Wraps `inner`.
    pub fn new(inner: B) -> Self {
        KernedText { inner }
    }
    /// The wrapped backend.
    pub fn into_inner(self) -> B {
        self.inner
    }
}

/// The layout box plotters expects: top-left `(0, 0)`, the text's advance width and its full line height.
fn box_size(s: &str, size: f64) -> (i32, i32) {
    let e = text::measure(s, size as f32);
    (e.width.ceil() as i32, e.height().ceil() as i32)
}

impl<B: DrawingBackend> DrawingBackend for KernedText<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }
    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }
    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }
    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }
    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }
    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }
    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_path(path, style)
    }
    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (iw, ih): (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, (iw, ih), src)
    }

    fn estimate_text_size<TStyle: BackendTextStyle>(
        &self,
        s: &str,
        style: &TStyle,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        let (w, h) = box_size(s, style.size());
        Ok((w.max(0) as u32, h.max(0) as u32))
    }

    fn draw_text<TStyle: BackendTextStyle>(
        &mut self,
        s: &str,
        style: &TStyle,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let size = style.size() as f32;
        let l = text::layout(s, size);
        let (w, h) = box_size(s, style.size());
        // As plotters does: anchor offsets in the unrotated box, then the rotation about `pos`.
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -w,
            HPos::Center => -w / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -h / 2,
            VPos::Bottom => -h,
        };
        let trans = style.transform();
        let (sw, sh) = self.get_size();
        let mut pixels = Vec::new();
        l.rasterise(
            (0.0, 0.0),
            text::HAlign::Left,
            text::VAlign::Top,
            text::Rotation::None,
            |x, y, c| {
                pixels.push((x, y, c));
            },
        );
        for (x, y, c) in pixels {
            let (x, y) = match trans {
                FontTransform::None => (x + dx, y + dy),
                FontTransform::Rotate90 => (-(y + dy), x + dx),
                FontTransform::Rotate180 => (-(x + dx), -(y + dy)),
                FontTransform::Rotate270 => (y + dy, -(x + dx)),
            };
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && y >= 0 && (x as u32) < sw && (y as u32) < sh {
                self.inner.draw_pixel(
                    (x, y),
                    BackendColor {
                        alpha: color.alpha * f64::from(c.clamp(0.0, 1.0)),
                        rgb: color.rgb,
                    },
                )?;
            }
        }
        Ok(())
    }
}
