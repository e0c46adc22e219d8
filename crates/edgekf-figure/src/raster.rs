//! The pixel layer: an RGB canvas, anti-aliased coverage buffers (strokes, dashes, markers, bands), clipping of
//! far-away coordinates in `f64` before anything becomes an integer, and per-column thinning of long series.
//!
//! Everything is drawn first into a coverage buffer (per pixel the maximum coverage of one colour) and then
//! composited once, so overlapping segments of one curve do not darken their joints and a translucent band is
//! blended exactly once per pixel.

use std::path::Path;

use super::FigureError;

/// An sRGB colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// White.
    pub const WHITE: Rgb = Rgb(255, 255, 255);
    /// Black.
    pub const BLACK: Rgb = Rgb(0, 0, 0);

    /// Mixes `self` with `other`: `t = 0` gives `self`, `t = 1` gives `other`.
    pub fn mix(self, other: Rgb, t: f32) -> Rgb {
        let t = t.clamp(0.0, 1.0);
        let m = |a: u8, b: u8| (f32::from(a) * (1.0 - t) + f32::from(b) * t).round() as u8;
        Rgb(m(self.0, other.0), m(self.1, other.1), m(self.2, other.2))
    }
}

/// A rectangle in pixel coordinates (y grows downwards), `x0 ≤ x1`, `y0 ≤ y1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PxRect {
    /// Left edge.
    pub x0: f64,
    /// Top edge.
    pub y0: f64,
    /// Right edge.
    pub x1: f64,
    /// Bottom edge.
    pub y1: f64,
}

impl PxRect {
    /// The rectangle from its edges (reordered if needed).
    pub fn new(x0: f64, y0: f64, x1: f64, y1: f64) -> Self {
        PxRect {
            x0: x0.min(x1),
            y0: y0.min(y1),
            x1: x0.max(x1),
            y1: y0.max(y1),
        }
    }
    /// Width.
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }
    /// Height.
    pub fn height(&self) -> f64 {
        self.y1 - self.y0
    }
    /// Whether the two rectangles share interior points.
    pub fn intersects(&self, o: &PxRect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    /// Whether `o` lies inside `self`.
    pub fn contains(&self, o: &PxRect) -> bool {
        o.x0 >= self.x0 && o.x1 <= self.x1 && o.y0 >= self.y0 && o.y1 <= self.y1
    }
    /// The rectangle grown by `d` on every side.
    pub fn grow(&self, d: f64) -> PxRect {
        PxRect::new(self.x0 - d, self.y0 - d, self.x1 + d, self.y1 + d)
    }
}

/// An RGB image that figures are drawn on; saved as PNG (indexed when it has at most 256 colours).
#[derive(Clone, Debug)]
pub struct Canvas {
    w: u32,
    h: u32,
    px: Vec<u8>,
}

impl Canvas {
    /// A white canvas of `w × h` pixels (at least 1 × 1).
    pub fn new(w: u32, h: u32) -> Self {
        let (w, h) = (w.max(1), h.max(1));
        Canvas {
            w,
            h,
            px: vec![255; (w as usize) * (h as usize) * 3],
        }
    }
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.w
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.h
    }
    /// The pixels, row-major RGB.
    pub fn rgb(&self) -> &[u8] {
        &self.px
    }
    /// The colour at `(x, y)` (white outside the canvas).
    pub fn pixel(&self, x: i32, y: i32) -> Rgb {
        if x < 0 || y < 0 || x as u32 >= self.w || y as u32 >= self.h {
            return Rgb::WHITE;
        }
        let i = (y as usize * self.w as usize + x as usize) * 3;
        Rgb(self.px[i], self.px[i + 1], self.px[i + 2])
    }
    /// Blends `c` with opacity `a` into the pixel `(x, y)`; outside the canvas nothing happens.
    pub fn blend(&mut self, x: i32, y: i32, c: Rgb, a: f32) {
        if x < 0 || y < 0 || x as u32 >= self.w || y as u32 >= self.h || a <= 0.0 {
            return;
        }
        let a = a.min(1.0);
        let i = (y as usize * self.w as usize + x as usize) * 3;
        for (k, v) in [c.0, c.1, c.2].into_iter().enumerate() {
            let old = f32::from(self.px[i + k]);
            self.px[i + k] = (old + (f32::from(v) - old) * a).round() as u8;
        }
    }
    /// Fills the pixels whose centres lie in `r` with `c` at opacity `a`.
    pub fn fill_rect(&mut self, r: PxRect, c: Rgb, a: f32) {
        let x0 = r.x0.round().max(0.0) as i32;
        let x1 = r.x1.round().min(f64::from(self.w)) as i32;
        let y0 = r.y0.round().max(0.0) as i32;
        let y1 = r.y1.round().min(f64::from(self.h)) as i32;
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, c, a);
            }
        }
    }
    /// Draws a one-pixel frame just inside the pixel edges of `r` (crisp: no anti-aliasing).
    pub fn frame(&mut self, r: PxRect, c: Rgb) {
        let (x0, y0) = (r.x0.round() as i32, r.y0.round() as i32);
        let (x1, y1) = (r.x1.round() as i32 - 1, r.y1.round() as i32 - 1);
        for x in x0..=x1 {
            self.blend(x, y0, c, 1.0);
            self.blend(x, y1, c, 1.0);
        }
        for y in y0..=y1 {
            self.blend(x0, y, c, 1.0);
            self.blend(x1, y, c, 1.0);
        }
    }
    /// A canvas from row-major RGB pixels (`None` when the length is not `w × h × 3`).
    pub fn from_rgb(w: u32, h: u32, px: Vec<u8>) -> Option<Canvas> {
        (w > 0 && h > 0 && px.len() == (w as usize) * (h as usize) * 3).then_some(Canvas {
            w,
            h,
            px,
        })
    }
    /// A copy enlarged `k` times with square pixels (to inspect text and antialiasing by eye).
    pub fn zoomed(&self, k: u32) -> Canvas {
        let k = k.clamp(1, 16);
        let mut out = Canvas::new(self.w * k, self.h * k);
        for y in 0..out.h {
            for x in 0..out.w {
                let c = self.pixel((x / k) as i32, (y / k) as i32);
                out.blend(x as i32, y as i32, c, 1.0);
            }
        }
        out
    }
    /// Copies `src` onto this canvas with its top-left corner at `(x, y)`.
    pub fn paste(&mut self, src: &Canvas, x: i32, y: i32) {
        for j in 0..src.h as i32 {
            for i in 0..src.w as i32 {
                self.blend(x + i, y + j, src.pixel(i, j), 1.0);
            }
        }
    }
    /// Draws marked-up text (see [`super::text`]) anchored at `at`; returns its box.
    pub fn draw_text(
        &mut self,
        s: &str,
        size: f32,
        at: (f64, f64),
        h: super::text::HAlign,
        v: super::text::VAlign,
        colour: Rgb,
    ) -> PxRect {
        let l = super::text::layout(s, size);
        let (x0, y0, x1, y1) = l.bounds(
            (at.0 as f32, at.1 as f32),
            h,
            v,
            super::text::Rotation::None,
        );
        let mut cov = Coverage::new(
            PxRect::new(f64::from(x0), f64::from(y0), f64::from(x1), f64::from(y1)).grow(4.0),
        );
        l.rasterise(
            (at.0 as f32, at.1 as f32),
            h,
            v,
            super::text::Rotation::None,
            |x, y, c| cov.put(x, y, c),
        );
        cov.composite(self, colour, 1.0);
        PxRect::new(f64::from(x0), f64::from(y0), f64::from(x1), f64::from(y1))
    }
    /// Writes the canvas as a PNG file: 8-bit indexed when it has at most 256 colours (exact, the
    /// same pixels), RGB otherwise, at the encoder's best compression.
    ///
    /// # Errors
    /// When the file cannot be written or encoded.
    pub fn save_png(&self, path: &Path) -> Result<(), FigureError> {
        let fail =
            |e: &dyn std::fmt::Display| FigureError::Encode(format!("{}: {e}", path.display()));
        let file = std::fs::File::create(path).map_err(|e| fail(&e))?;
        let bytes = self.encode_png().map_err(|e| fail(&e))?;
        let mut w = std::io::BufWriter::new(file);
        std::io::Write::write_all(&mut w, &bytes).map_err(|e| fail(&e))?;
        std::io::Write::flush(&mut w).map_err(|e| fail(&e))?;
        Ok(())
    }

    /// The canvas encoded as PNG bytes (see [`Canvas::save_png`]).
    ///
    /// # Errors
    /// When the encoder fails.
    pub fn encode_png(&self) -> Result<Vec<u8>, png::EncodingError> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.w, self.h);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Best);
        let data = match self.palette() {
            Some((palette, index)) => {
                enc.set_color(png::ColorType::Indexed);
                enc.set_palette(palette);
                enc.set_filter(png::FilterType::NoFilter);
                index
            }
            None => {
                enc.set_color(png::ColorType::Rgb);
                enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
                self.px.clone()
            }
        };
        let mut writer = enc.write_header()?;
        writer.write_image_data(&data)?;
        writer.finish()?;
        Ok(out)
    }

    /// The palette (RGB triples) and per-pixel indices, when the canvas has at most 256 colours.
    fn palette(&self) -> Option<(Vec<u8>, Vec<u8>)> {
        let mut seen: std::collections::HashMap<[u8; 3], u8> = std::collections::HashMap::new();
        let mut palette = Vec::new();
        let mut index = Vec::with_capacity(self.px.len() / 3);
        for p in self.px.chunks_exact(3) {
            let key = [p[0], p[1], p[2]];
            let i = match seen.get(&key) {
                Some(&i) => i,
                None => {
                    let i = u8::try_from(seen.len()).ok()?;
                    seen.insert(key, i);
                    palette.extend_from_slice(&key);
                    i
                }
            };
            index.push(i);
        }
        Some((palette, index))
    }
}

/// Per-pixel coverage (0–1) of one colour over a clip rectangle; the maximum wins where shapes overlap.
#[derive(Clone, Debug)]
pub(crate) struct Coverage {
    x0: i32,
    y0: i32,
    w: i32,
    h: i32,
    a: Vec<f32>,
    /// Touched bounding box (inclusive), to composite only what was drawn.
    tb: Option<(i32, i32, i32, i32)>,
}

impl Coverage {
    /// An empty buffer over the pixels of `clip` (rounded outwards, at least one pixel).
    pub fn new(clip: PxRect) -> Self {
        let x0 = clip.x0.floor() as i32;
        let y0 = clip.y0.floor() as i32;
        let w = ((clip.x1.ceil() as i32) - x0).max(1);
        let h = ((clip.y1.ceil() as i32) - y0).max(1);
        Coverage {
            x0,
            y0,
            w,
            h,
            a: vec![0.0; (w as usize) * (h as usize)],
            tb: None,
        }
    }

    /// The clip rectangle in pixels.
    pub fn rect(&self) -> PxRect {
        PxRect::new(
            f64::from(self.x0),
            f64::from(self.y0),
            f64::from(self.x0 + self.w),
            f64::from(self.y0 + self.h),
        )
    }

    /// Raises the coverage of pixel `(x, y)` to at least `c`.
    #[inline]
    pub fn put(&mut self, x: i32, y: i32, c: f32) {
        let (lx, ly) = (x - self.x0, y - self.y0);
        if lx < 0 || ly < 0 || lx >= self.w || ly >= self.h || c <= 0.0 {
            return;
        }
        let i = (ly * self.w + lx) as usize;
        if c > self.a[i] {
            self.a[i] = c.min(1.0);
        }
        self.tb = Some(match self.tb {
            None => (x, y, x, y),
            Some((a, b, c2, d)) => (a.min(x), b.min(y), c2.max(x), d.max(y)),
        });
    }

    /// The coverage at `(x, y)`.
    #[cfg(test)]
    pub fn get(&self, x: i32, y: i32) -> f32 {
        let (lx, ly) = (x - self.x0, y - self.y0);
        if lx < 0 || ly < 0 || lx >= self.w || ly >= self.h {
            return 0.0;
        }
        self.a[(ly * self.w + lx) as usize]
    }

    /// Calls `f(x, y, coverage)` for every touched pixel with nonzero coverage.
    pub fn for_each(&self, mut f: impl FnMut(i32, i32, f32)) {
        let Some((xa, ya, xb, yb)) = self.tb else {
            return;
        };
        for y in ya..=yb {
            let row = ((y - self.y0) * self.w) as usize;
            for x in xa..=xb {
                let c = self.a[row + (x - self.x0) as usize];
                if c > 0.0 {
                    f(x, y, c);
                }
            }
        }
    }

    /// Blends the buffer onto `canvas` in colour `c` with overall opacity `opacity`.
    pub fn composite(&self, canvas: &mut Canvas, c: Rgb, opacity: f32) {
        self.for_each(|x, y, a| canvas.blend(x, y, c, a * opacity));
    }

    /// A copy grown by `r` pixels (a halo behind text), coverage falling off over the last pixel.
    pub fn dilated(&self, r: f32) -> Coverage {
        let mut out = Coverage {
            x0: self.x0,
            y0: self.y0,
            w: self.w,
            h: self.h,
            a: vec![0.0; self.a.len()],
            tb: None,
        };
        let ri = r.ceil() as i32 + 1;
        self.for_each(|x, y, c| {
            for dy in -ri..=ri {
                for dx in -ri..=ri {
                    let d = ((dx * dx + dy * dy) as f32).sqrt();
                    let k = (r + 0.5 - d).clamp(0.0, 1.0) * c.max(0.5);
                    out.put(x + dx, y + dy, k);
                }
            }
        });
        out
    }

    /// Strokes the segment `a`–`b` with round caps and width `width` (anti-aliased).
    pub fn segment(&mut self, a: (f64, f64), b: (f64, f64), width: f64) {
        let r = (width / 2.0).max(0.3);
        let clip = self.rect().grow(r + 2.0);
        let Some((a, b)) = clip_segment(a, b, &clip) else {
            return;
        };
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        let mut pix = |x: i32, y: i32| {
            let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            let t = if len2 > 0.0 {
                (((px - a.0) * dx + (py - a.1) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (qx, qy) = (a.0 + t * dx - px, a.1 + t * dy - py);
            let d = (qx * qx + qy * qy).sqrt();
            let c = (r + 0.5 - d).clamp(0.0, 1.0).min(2.0 * r);
            self.put(x, y, c as f32);
        };
        let m = r + 1.5;
        if dx.abs() >= dy.abs() {
            let (l, rr) = if a.0 <= b.0 { (a, b) } else { (b, a) };
            let slope = if rr.0 > l.0 {
                (rr.1 - l.1) / (rr.0 - l.0)
            } else {
                0.0
            };
            let span = m * (1.0 + slope * slope).sqrt() + 1.0;
            for x in (l.0 - m).floor() as i32..=(rr.0 + m).ceil() as i32 {
                let xc = (f64::from(x) + 0.5).clamp(l.0, rr.0);
                let yc = l.1 + slope * (xc - l.0);
                for y in (yc - span).floor() as i32..=(yc + span).ceil() as i32 {
                    pix(x, y);
                }
            }
        } else {
            let (t, bt) = if a.1 <= b.1 { (a, b) } else { (b, a) };
            let slope = if bt.1 > t.1 {
                (bt.0 - t.0) / (bt.1 - t.1)
            } else {
                0.0
            };
            let span = m * (1.0 + slope * slope).sqrt() + 1.0;
            for y in (t.1 - m).floor() as i32..=(bt.1 + m).ceil() as i32 {
                let yc = (f64::from(y) + 0.5).clamp(t.1, bt.1);
                let xc = t.0 + slope * (yc - t.1);
                for x in (xc - span).floor() as i32..=(xc + span).ceil() as i32 {
                    pix(x, y);
                }
            }
        }
    }

    /// Strokes a polyline, solid or with the dash `pattern` (on, off, on, off, … in pixels), the pattern running
    /// on across vertices.
    pub fn polyline(&mut self, pts: &[(f64, f64)], width: f64, pattern: Option<&[f64]>) {
        if pts.len() == 1 {
            self.segment(pts[0], pts[0], width);
            return;
        }
        let Some(pat) = pattern.filter(|p| p.len() >= 2 && p.iter().all(|v| *v > 0.0)) else {
            for w in pts.windows(2) {
                self.segment(w[0], w[1], width);
            }
            return;
        };
        let period: f64 = pat.iter().sum();
        let clip = self.rect().grow(width + 2.0);
        let (mut k, mut left) = (0usize, pat[0]);
        for w in pts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
            if !len.is_finite() || len == 0.0 {
                continue;
            }
            // Skip the parts outside the clip without walking them dash by dash.
            let Some((ca, cb)) = clip_segment(a, b, &clip) else {
                advance(&mut k, &mut left, pat, len % period);
                continue;
            };
            let lead = ((ca.0 - a.0).powi(2) + (ca.1 - a.1).powi(2)).sqrt();
            advance(&mut k, &mut left, pat, lead % period);
            let vis = ((cb.0 - ca.0).powi(2) + (cb.1 - ca.1).powi(2)).sqrt();
            let (ux, uy) = ((b.0 - a.0) / len, (b.1 - a.1) / len);
            let mut s = 0.0;
            while s < vis {
                let step = left.min(vis - s);
                if k % 2 == 0 {
                    let p = (ca.0 + ux * s, ca.1 + uy * s);
                    let q = (ca.0 + ux * (s + step), ca.1 + uy * (s + step));
                    self.segment(p, q, width);
                }
                s += step;
                left -= step;
                if left <= 1e-9 {
                    k = (k + 1) % pat.len();
                    left = pat[k];
                }
            }
            let tail = len - lead - vis;
            advance(&mut k, &mut left, pat, tail.max(0.0) % period);
        }
    }

    /// Fills the region between per-column heights, `cols[i] = (x, top, bottom)` for pixel column `x`
    /// (fractional `top`/`bottom` give anti-aliased edges; `frac` is the horizontal share of the column).
    pub fn columns(&mut self, cols: impl IntoIterator<Item = (i32, f64, f64, f64)>) {
        for (x, top, bottom, frac) in cols {
            if !(top.is_finite() && bottom.is_finite()) || bottom <= top {
                continue;
            }
            let r = self.rect();
            let (top, bottom) = (top.max(r.y0 - 1.0), bottom.min(r.y1 + 1.0));
            if bottom <= top {
                continue;
            }
            for y in top.floor() as i32..=bottom.ceil() as i32 {
                let (p0, p1) = (f64::from(y), f64::from(y) + 1.0);
                let overlap = (p1.min(bottom) - p0.max(top)).max(0.0);
                self.put(x, y, (overlap * frac) as f32);
            }
        }
    }

    /// Stamps a marker (see [`Stamp`]) centred at `c`.
    pub fn stamp(&mut self, s: &Stamp, c: (f64, f64)) {
        if !(c.0.is_finite() && c.1.is_finite()) {
            return;
        }
        let r = self.rect().grow(f64::from(s.half) + 2.0);
        if c.0 < r.x0 || c.0 > r.x1 || c.1 < r.y0 || c.1 > r.y1 {
            return;
        }
        let (fx, fy) = (c.0 - c.0.floor(), c.1 - c.1.floor());
        let (qx, qy) = (((fx * 4.0) as usize).min(3), ((fy * 4.0) as usize).min(3));
        let img = &s.phases[qy * 4 + qx];
        let n = 2 * s.half + 1;
        let (bx, by) = (c.0.floor() as i32 - s.half, c.1.floor() as i32 - s.half);
        for j in 0..n {
            for i in 0..n {
                let v = img[(j * n + i) as usize];
                if v > 0.0 {
                    self.put(bx + i, by + j, v);
                }
            }
        }
    }
}

/// Moves a dash pattern's state forward by `d` pixels.
fn advance(k: &mut usize, left: &mut f64, pat: &[f64], mut d: f64) {
    while d > 0.0 {
        if d < *left {
            *left -= d;
            return;
        }
        d -= *left;
        *k = (*k + 1) % pat.len();
        *left = pat[*k];
    }
}

/// Liang–Barsky clipping of the segment `a`–`b` to `r` (in `f64`: coordinates may be astronomically large).
pub(crate) fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    r: &PxRect,
) -> Option<((f64, f64), (f64, f64))> {
    if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
        return None;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    if !(dx.is_finite() && dy.is_finite()) {
        // Both ends finite but the difference overflows: halve and retry on each half.
        let m = (a.0 / 2.0 + b.0 / 2.0, a.1 / 2.0 + b.1 / 2.0);
        return match (clip_segment(a, m, r), clip_segment(m, b, r)) {
            (Some((p, _)), Some((_, q))) => Some((p, q)),
            (Some(s), None) | (None, Some(s)) => Some(s),
            (None, None) => None,
        };
    }
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - r.x0),
        (dx, r.x1 - a.0),
        (-dy, a.1 - r.y0),
        (dy, r.y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
            if t0 > t1 {
                return None;
            }
        }
    }
    Some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

/// Marker shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// ●
    Circle,
    /// ■
    Square,
    /// ◆
    Diamond,
    /// ▲
    TriangleUp,
    /// ▼
    TriangleDown,
    /// ×
    Cross,
    /// +
    Plus,
}

/// A marker pre-rendered at 4 × 4 sub-pixel offsets, so that a million markers cost a million small copies.
#[derive(Clone, Debug)]
pub(crate) struct Stamp {
    half: i32,
    phases: Vec<Vec<f32>>,
}

impl Stamp {
    /// Renders `shape` of diameter `size` pixels, filled or outlined with `line` pixels.
    pub fn new(shape: Shape, size: f64, filled: bool, line: f64) -> Stamp {
        let size = if size.is_finite() {
            size.clamp(1.0, 200.0)
        } else {
            6.0
        };
        let half = (size / 2.0 + line + 2.0).ceil() as i32;
        let n = 2 * half + 1;
        let mut phases = Vec::with_capacity(16);
        for qy in 0..4 {
            for qx in 0..4 {
                let c = (
                    f64::from(half) + f64::from(qx) / 4.0 + 0.125,
                    f64::from(half) + f64::from(qy) / 4.0 + 0.125,
                );
                let mut cov = Coverage::new(PxRect::new(0.0, 0.0, f64::from(n), f64::from(n)));
                draw_shape(&mut cov, shape, c, size / 2.0, filled, line);
                phases.push(cov.a);
            }
        }
        Stamp { half, phases }
    }
}

/// The outline of a polygonal shape of radius `r` around `c`.
fn shape_polygon(shape: Shape, c: (f64, f64), r: f64) -> Vec<(f64, f64)> {
    match shape {
        Shape::Square => {
            let s = r * 0.85;
            vec![
                (c.0 - s, c.1 - s),
                (c.0 + s, c.1 - s),
                (c.0 + s, c.1 + s),
                (c.0 - s, c.1 + s),
            ]
        }
        Shape::Diamond => vec![
            (c.0, c.1 - r * 1.15),
            (c.0 + r * 0.85, c.1),
            (c.0, c.1 + r * 1.15),
            (c.0 - r * 0.85, c.1),
        ],
        Shape::TriangleUp => vec![
            (c.0, c.1 - r * 1.1),
            (c.0 + r, c.1 + r * 0.7),
            (c.0 - r, c.1 + r * 0.7),
        ],
        Shape::TriangleDown => vec![
            (c.0, c.1 + r * 1.1),
            (c.0 - r, c.1 - r * 0.7),
            (c.0 + r, c.1 - r * 0.7),
        ],
        _ => Vec::new(),
    }
}

fn draw_shape(cov: &mut Coverage, shape: Shape, c: (f64, f64), r: f64, filled: bool, line: f64) {
    match shape {
        Shape::Circle => {
            let ri = (r + line + 1.0).ceil() as i32;
            let (cx, cy) = (c.0.floor() as i32, c.1.floor() as i32);
            for y in cy - ri..=cy + ri {
                for x in cx - ri..=cx + ri {
                    let d = ((f64::from(x) + 0.5 - c.0).powi(2)
                        + (f64::from(y) + 0.5 - c.1).powi(2))
                    .sqrt();
                    let v = if filled {
                        (r + 0.5 - d).clamp(0.0, 1.0)
                    } else {
                        (line / 2.0 + 0.5 - (d - r).abs()).clamp(0.0, 1.0)
                    };
                    cov.put(x, y, v as f32);
                }
            }
        }
        Shape::Cross => {
            let s = r * 0.8;
            let w = line.max(1.5);
            cov.segment((c.0 - s, c.1 - s), (c.0 + s, c.1 + s), w);
            cov.segment((c.0 - s, c.1 + s), (c.0 + s, c.1 - s), w);
        }
        Shape::Plus => {
            let w = line.max(1.5);
            cov.segment((c.0 - r, c.1), (c.0 + r, c.1), w);
            cov.segment((c.0, c.1 - r), (c.0, c.1 + r), w);
        }
        _ => {
            let poly = shape_polygon(shape, c, r);
            if filled {
                fill_convex(cov, &poly);
            } else {
                let mut closed = poly.clone();
                closed.push(poly[0]);
                cov.polyline(&closed, line, None);
            }
        }
    }
}

/// Fills a convex polygon with 4 × 4 supersampling.
fn fill_convex(cov: &mut Coverage, poly: &[(f64, f64)]) {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in poly {
        x0 = x0.min(p.0);
        y0 = y0.min(p.1);
        x1 = x1.max(p.0);
        y1 = y1.max(p.1);
    }
    let inside = |x: f64, y: f64| {
        let mut sign = 0i8;
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let cr = (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0);
            let s = if cr > 0.0 {
                1
            } else if cr < 0.0 {
                -1
            } else {
                0
            };
            if s != 0 {
                if sign == 0 {
                    sign = s;
                } else if sign != s {
                    return false;
                }
            }
        }
        true
    };
    for y in y0.floor() as i32..=y1.ceil() as i32 {
        for x in x0.floor() as i32..=x1.ceil() as i32 {
            let mut n = 0;
            for j in 0..4 {
                for i in 0..4 {
                    if inside(
                        f64::from(x) + (f64::from(i) + 0.5) / 4.0,
                        f64::from(y) + (f64::from(j) + 0.5) / 4.0,
                    ) {
                        n += 1;
                    }
                }
            }
            cov.put(x, y, n as f32 / 16.0);
        }
    }
}

/// Thins a run of pixel-space points: consecutive points in the same pixel column are replaced by the first,
/// the lowest, the highest and the last of them (in their original order), which draws the same pixels.
pub(crate) fn thin_columns(pts: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if pts.len() <= 4 {
        return pts.to_vec();
    }
    let mut out = Vec::with_capacity(pts.len().min(8192));
    let mut i = 0;
    while i < pts.len() {
        let col = pts[i].0.floor();
        let mut j = i + 1;
        while j < pts.len() && pts[j].0.floor() == col {
            j += 1;
        }
        if j - i <= 4 {
            out.extend_from_slice(&pts[i..j]);
        } else {
            let (mut lo, mut hi) = (i, i);
            for k in i..j {
                if pts[k].1 < pts[lo].1 {
                    lo = k;
                }
                if pts[k].1 > pts[hi].1 {
                    hi = k;
                }
            }
            let mut keep = [i, lo, hi, j - 1];
            keep.sort_unstable();
            let mut last = usize::MAX;
            for k in keep {
                if k != last {
                    out.push(pts[k]);
                    last = k;
                }
            }
        }
        i = j;
    }
    out
}

/// Per-column extent of the band between two pixel-space edges sampled at the same x (`upper` has the smaller
/// pixel y). Returns `(column, top, bottom, horizontal share)` for the columns the band covers inside `[xa, xb]`.
pub(crate) fn band_columns(
    x: &[f64],
    upper: &[f64],
    lower: &[f64],
    xa: f64,
    xb: f64,
) -> Vec<(i32, f64, f64, f64)> {
    let (c_lo, c_hi) = (xa.floor() as i32, xb.ceil() as i32);
    if c_hi <= c_lo || c_hi - c_lo > 100_000 {
        return Vec::new();
    }
    // Per column: (top, bottom, left, right) over the pieces of band in it.
    let mut cols = vec![
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY
        );
        (c_hi - c_lo) as usize
    ];
    let ok = |i: usize| x[i].is_finite() && upper[i].is_finite() && lower[i].is_finite();
    let n = x.len().min(upper.len()).min(lower.len());
    for i in 0..n.saturating_sub(1) {
        if !(ok(i) && ok(i + 1)) {
            continue;
        }
        let (xl, xr) = (x[i].min(x[i + 1]).max(xa), x[i].max(x[i + 1]).min(xb));
        if xl > xr {
            continue;
        }
        let dx = x[i + 1] - x[i];
        let at = |v: &[f64], t: f64| {
            if dx == 0.0 {
                v[i]
            } else {
                v[i] + (v[i + 1] - v[i]) * ((t - x[i]) / dx).clamp(0.0, 1.0)
            }
        };
        let c0 = (xl.floor() as i32).max(c_lo);
        let c1 = ((xr.ceil() as i32) - 1).max(c0).min(c_hi - 1);
        for c in c0..=c1 {
            let (l, r) = (f64::from(c).max(xl), (f64::from(c) + 1.0).min(xr));
            let (u0, u1) = (at(upper, l), at(upper, r));
            let (w0, w1) = (at(lower, l), at(lower, r));
            let e = &mut cols[(c - c_lo) as usize];
            e.0 = e.0.min(u0.min(u1).min(w0).min(w1));
            e.1 = e.1.max(u0.max(u1).max(w0).max(w1));
            e.2 = e.2.min(l);
            e.3 = e.3.max(r);
        }
    }
    cols.into_iter()
        .enumerate()
        .filter(|(_, e)| e.0 <= e.1)
        .map(|(k, (t, b, l, r))| {
            // A zero-width piece (all points in one column at one x) is drawn one pixel wide.
            let share = if r > l { (r - l).min(1.0) } else { 1.0 };
            (c_lo + k as i32, t, b, share)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_handles_astronomic_coordinates() {
        let r = PxRect::new(0.0, 0.0, 100.0, 100.0);
        // Pixel coordinates stay within ±10⁴ plot sizes (see `render::FAR`): clipping is exact there.
        let s = clip_segment((-1e7, 50.0), (1e7, 50.0), &r).expect("crosses");
        assert!((s.0 .0 - 0.0).abs() < 1e-6 && (s.1 .0 - 100.0).abs() < 1e-6);
        // Beyond, clipping loses precision but stays finite and never panics.
        let s = clip_segment((-1e303, 50.0), (1e303, 50.0), &r).expect("crosses");
        assert!(s.0 .0.is_finite() && s.1 .0.is_finite());
        assert!(clip_segment((-f64::MAX, 0.0), (f64::MAX, 200.0), &r).is_some());
        assert!(clip_segment((200.0, 0.0), (300.0, 0.0), &r).is_none());
        assert!(clip_segment((f64::NAN, 0.0), (3.0, 3.0), &r).is_none());
    }

    #[test]
    fn thinning_keeps_each_columns_extremes() {
        let pts: Vec<(f64, f64)> = (0..1000)
            .map(|i| (f64::from(i) / 100.0, f64::from((i * 37) % 101)))
            .collect();
        let t = thin_columns(&pts);
        assert!(t.len() <= 40);
        for c in 0..10 {
            let col = |v: &[(f64, f64)]| {
                v.iter()
                    .filter(|p| p.0.floor() as i32 == c)
                    .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)))
            };
            assert_eq!(col(&pts), col(&t));
        }
    }

    #[test]
    fn dashes_leave_gaps_and_solid_does_not() {
        let mut solid = Coverage::new(PxRect::new(0.0, 0.0, 100.0, 10.0));
        solid.polyline(&[(0.0, 5.0), (100.0, 5.0)], 1.5, None);
        let mut dashed = Coverage::new(PxRect::new(0.0, 0.0, 100.0, 10.0));
        dashed.polyline(
            &[(0.0, 5.0), (50.0, 5.0), (100.0, 5.0)],
            1.5,
            Some(&[6.0, 4.0]),
        );
        let on = |c: &Coverage| (0..100).filter(|&x| c.get(x, 5) > 0.5).count();
        assert_eq!(on(&solid), 100);
        let d = on(&dashed);
        assert!((50..=85).contains(&d), "{d} of 100 columns inked");
    }
}
