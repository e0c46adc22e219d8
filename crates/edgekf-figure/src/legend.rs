//! Legend placement, computed from what is drawn: among candidate boxes inside the plot area (corners, edge
//! middles) the one over the fewest data pixels wins (lines and markers weigh [`LINE_WEIGHT`], translucent bands
//! [`BAND_WEIGHT`]); when even the best one would cover data, the legend goes outside, right of the plot.

use super::raster::PxRect;

/// Occupancy weight of a line, marker or label pixel.
pub const LINE_WEIGHT: u16 = 8;
/// Occupancy weight of a band pixel.
pub const BAND_WEIGHT: u16 = 1;
/// A box "fits" when its weighted occupancy is at most this share of its area × [`BAND_WEIGHT`]
/// (a few pixels of a band's edge, no line).
pub const FIT_SHARE: f64 = 0.003;
/// Distance between a legend box and the plot frame, in pixels.
pub const INSET_PX: f64 = 8.0;

/// Where a legend (or an inset) went.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Placement {
    /// Inside, top right.
    UpperRight,
    /// Inside, top left.
    UpperLeft,
    /// Inside, bottom right.
    LowerRight,
    /// Inside, bottom left.
    LowerLeft,
    /// Inside, top centre.
    UpperCenter,
    /// Inside, bottom centre.
    LowerCenter,
    /// Inside, right edge, middle.
    CenterRight,
    /// Inside, left edge, middle.
    CenterLeft,
    /// Outside the plot area, to its right.
    OutsideRight,
}

/// Inside candidates in order of preference (ties go to the earlier one).
pub const INSIDE: [Placement; 8] = [
    Placement::UpperRight,
    Placement::UpperLeft,
    Placement::LowerRight,
    Placement::LowerLeft,
    Placement::UpperCenter,
    Placement::LowerCenter,
    Placement::CenterRight,
    Placement::CenterLeft,
];

/// Weighted map of the pixels of a plot area that hold data.
#[derive(Clone, Debug)]
pub struct Occupancy {
    x0: i32,
    y0: i32,
    w: i32,
    h: i32,
    v: Vec<u16>,
}

impl Occupancy {
    /// An empty map over `r`.
    pub fn new(r: PxRect) -> Self {
        let (x0, y0) = (r.x0.floor() as i32, r.y0.floor() as i32);
        let w = (r.x1.ceil() as i32 - x0).max(1);
        let h = (r.y1.ceil() as i32 - y0).max(1);
        Occupancy {
            x0,
            y0,
            w,
            h,
            v: vec![0; (w * h) as usize],
        }
    }
    /// Adds `weight` at pixel `(x, y)` (saturating; outside the map nothing happens).
    pub fn add(&mut self, x: i32, y: i32, weight: u16) {
        let (lx, ly) = (x - self.x0, y - self.y0);
        if lx >= 0 && ly >= 0 && lx < self.w && ly < self.h {
            let i = (ly * self.w + lx) as usize;
            self.v[i] = self.v[i].saturating_add(weight);
        }
    }
    /// Adds `weight` on every pixel of `r`.
    pub fn add_rect(&mut self, r: PxRect, weight: u16) {
        for y in r.y0.floor() as i32..r.y1.ceil() as i32 {
            for x in r.x0.floor() as i32..r.x1.ceil() as i32 {
                self.add(x, y, weight);
            }
        }
    }
    /// Sum of the weights in `r`.
    pub fn sum(&self, r: PxRect) -> u64 {
        let xa = (r.x0.floor() as i32 - self.x0).clamp(0, self.w);
        let xb = (r.x1.ceil() as i32 - self.x0).clamp(0, self.w);
        let ya = (r.y0.floor() as i32 - self.y0).clamp(0, self.h);
        let yb = (r.y1.ceil() as i32 - self.y0).clamp(0, self.h);
        let mut s = 0u64;
        for y in ya..yb {
            let row = (y * self.w) as usize;
            s += self.v[row + xa as usize..row + xb as usize]
                .iter()
                .map(|&v| u64::from(v))
                .sum::<u64>();
        }
        s
    }
}

/// The box of size `(w, h)` at `p` inside `plot`.
pub fn candidate(plot: PxRect, p: Placement, w: f64, h: f64) -> PxRect {
    let m = INSET_PX;
    let (l, r) = (plot.x0 + m, plot.x1 - m - w);
    let (t, b) = (plot.y0 + m, plot.y1 - m - h);
    let (cx, cy) = ((plot.x0 + plot.x1 - w) / 2.0, (plot.y0 + plot.y1 - h) / 2.0);
    let (x, y) = match p {
        Placement::UpperRight => (r, t),
        Placement::UpperLeft => (l, t),
        Placement::LowerRight => (r, b),
        Placement::LowerLeft => (l, b),
        Placement::UpperCenter => (cx, t),
        Placement::LowerCenter => (cx, b),
        Placement::CenterRight => (r, cy),
        Placement::CenterLeft => (l, cy),
        Placement::OutsideRight => (plot.x1 + 2.0 * m, plot.y0),
    };
    PxRect::new(x, y, x + w, y + h)
}

/// The inside candidate covering the least data: `(placement, box, weighted occupancy)`.
pub fn best(plot: PxRect, w: f64, h: f64, occ: &Occupancy) -> (Placement, PxRect, u64) {
    INSIDE
        .iter()
        .map(|&p| {
            let r = candidate(plot, p, w, h);
            (p, r, occ.sum(r))
        })
        .min_by_key(|c| c.2)
        .expect("INSIDE is not empty")
}

/// The best inside placement for a `(w, h)` box: `(placement, box, weighted occupancy)`, or `None` when the box
/// does not fit in the plot area or every candidate covers data beyond [`FIT_SHARE`].
pub fn choose(plot: PxRect, w: f64, h: f64, occ: &Occupancy) -> Option<(Placement, PxRect, u64)> {
    if w + 2.0 * INSET_PX > plot.width() || h + 2.0 * INSET_PX > plot.height() {
        return None;
    }
    let best = best(plot, w, h, occ);
    let limit = FIT_SHARE * w * h * f64::from(BAND_WEIGHT);
    (best.2 as f64 <= limit).then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_avoids_the_data_bounding_boxes() {
        let plot = PxRect::new(100.0, 50.0, 900.0, 650.0);
        // Data fill the upper right and the lower left quarters.
        let data = [
            PxRect::new(500.0, 50.0, 900.0, 350.0),
            PxRect::new(100.0, 350.0, 500.0, 650.0),
        ];
        let mut occ = Occupancy::new(plot);
        for d in data {
            occ.add_rect(d, LINE_WEIGHT);
        }
        let (p, r, cost) = choose(plot, 200.0, 120.0, &occ).expect("a free corner");
        assert_eq!(cost, 0);
        assert_eq!(p, Placement::UpperLeft);
        assert!(data.iter().all(|d| !d.intersects(&r)));
        assert!(plot.contains(&r));
    }

    #[test]
    fn nothing_free_means_outside() {
        let plot = PxRect::new(0.0, 0.0, 400.0, 300.0);
        let mut occ = Occupancy::new(plot);
        for x in (0..400).step_by(20) {
            occ.add_rect(
                PxRect::new(f64::from(x), 0.0, f64::from(x) + 2.0, 300.0),
                LINE_WEIGHT,
            );
        }
        assert!(choose(plot, 120.0, 60.0, &occ).is_none());
        // Too big a box never fits inside.
        assert!(choose(plot, 390.0, 60.0, &Occupancy::new(plot)).is_none());
    }
}
