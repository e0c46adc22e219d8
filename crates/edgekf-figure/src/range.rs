//! Axis ranges that are always drawable: finite, of positive width, within ±[`LIMIT`], and on log axes strictly
//! positive and not stretched by a few stray tiny values.
//!
//! The caller passes only the values that are usable on the axis (finite, and positive on a log axis); what was
//! left out is counted by the caller. Here:
//! - values beyond ±[`LIMIT`] (or below 1/[`LIMIT`] on a log axis) are clamped for the range, counted, and drawn
//!   outside the axis;
//! - on a log axis, *stray* values — at most 1 % of the values, separated from all the others by a gap of more
//!   than [`GAP_DECADES`] decades — do not set the range: a single 1e300 from a diverging run does not squash
//!   the rest into one pixel row, nor a few 10⁻¹⁷ round-off values stretch the axis. They lie above (the
//!   *ceiling*) or below (the *floor*) the axis; lines run off its edge. Evenly spaced data (t = Δt, 2Δt, … on a
//!   log-time axis) have no such gap and keep their range;
//! - a log axis also reaches at most [`MAX_DECADES`] decades below its largest (non-stray) value: f64 round-off,
//!   e.g. 10⁻¹⁶ where an error is "exactly" zero, would otherwise take half the axis. Exact zeros never reach a
//!   log axis at all (the caller leaves them out);
//! - a zero-width range (a constant, a single point) is widened: ±5 % of the value (±1 for zero) on a linear
//!   axis, a factor √10 either way on a log axis; a range narrower than 10⁻⁹ of its magnitude likewise;
//! - no value at all gives 0–1 (linear) or 1–10 (log), and the report says the axis is empty.

use super::Scale;

/// Largest magnitude an axis range reaches (±1e300); beyond it values are clamped.
pub const LIMIT: f64 = 1e300;
/// Stray values lie more than this many decades below all other values of a log axis.
pub const GAP_DECADES: f64 = 2.0;
/// A log axis spans at most this many decades below its largest value.
pub const MAX_DECADES: i32 = 12;

/// Why a log axis got a floor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FloorRule {
    /// At most 1 % of the values, more than [`GAP_DECADES`] below all others.
    Strays,
    /// [`MAX_DECADES`] below the largest value: round-off-sized values.
    DynamicRange,
}
/// Narrowest range relative to its magnitude; narrower ranges are widened to this.
pub const MIN_RELATIVE_WIDTH: f64 = 1e-9;

/// What the sanitiser did to one axis; part of the [`super::RenderReport`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AxisReport {
    /// Lower end of the drawn range.
    pub lo: f64,
    /// Upper end of the drawn range.
    pub hi: f64,
    /// Values beyond ±[`LIMIT`] (or below 1/[`LIMIT`] on a log axis), clamped for the range and drawn clipped.
    pub clamped: usize,
    /// The log axis floor and the rule that set it, when one applied.
    pub floor: Option<(f64, FloorRule)>,
    /// Positive values below the floor (they fall below the axis; lines run off its edge).
    pub below_floor: usize,
    /// Top of a log axis set below stray large values, when it applied.
    pub ceiling: Option<f64>,
    /// Stray values above the ceiling (they lie above the axis).
    pub above_ceiling: usize,
    /// The range was widened (zero or near-zero width).
    pub widened: bool,
    /// No usable value: the default range is shown.
    pub empty: bool,
    /// The axis range was fixed by the caller.
    pub fixed: bool,
    /// A fixed range was unusable (non-finite, empty, or not positive on a log axis) and was replaced.
    pub fixed_ignored: bool,
}

/// Computes the drawn range from the usable values `v` (they are reordered).
pub(crate) fn axis_range(
    v: &mut [f64],
    scale: Scale,
    fixed: Option<(f64, f64)>,
    margin: f64,
) -> AxisReport {
    let mut rep = AxisReport::default();
    if let Some((a, b)) = fixed {
        let (a, b) = (a.min(b), a.max(b));
        let ok = a.is_finite()
            && b.is_finite()
            && b > a
            && (scale == Scale::Linear || a > 0.0)
            && a.abs() <= LIMIT
            && b.abs() <= LIMIT;
        if ok {
            rep.lo = a;
            rep.hi = b;
            rep.fixed = true;
            return rep;
        }
        rep.fixed_ignored = true;
    }
    let log = scale == Scale::Log;
    let (lo_lim, hi_lim) = if log {
        (1.0 / LIMIT, LIMIT)
    } else {
        (-LIMIT, LIMIT)
    };
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.iter_mut() {
        if *x < lo_lim || *x > hi_lim {
            rep.clamped += 1;
            *x = x.clamp(lo_lim, hi_lim);
        }
        lo = lo.min(*x);
        hi = hi.max(*x);
    }
    if v.is_empty() || !(lo.is_finite() && hi.is_finite()) {
        rep.empty = true;
        (rep.lo, rep.hi) = if log { (1.0, 10.0) } else { (0.0, 1.0) };
        return rep;
    }
    if log {
        let k = v.len() / 100;
        if k > 0 {
            // The highest 1 % (and the next value below), sorted: a gap wider than GAP_DECADES?
            let n = v.len();
            v.select_nth_unstable_by(n - 1 - k, f64::total_cmp);
            v[n - 1 - k..].sort_unstable_by(f64::total_cmp);
            let gap = (n - 1 - k..n - 1).find(|&i| v[i + 1].log10() - v[i].log10() > GAP_DECADES);
            if let Some(i) = gap {
                rep.ceiling = Some(v[i]);
                rep.above_ceiling = n - 1 - i;
                hi = v[i];
            }
        }
        let mut floor = (hi * 10f64.powi(-MAX_DECADES), FloorRule::DynamicRange);
        if k > 0 {
            // The lowest 1 % (and the next value), sorted: a gap wider than GAP_DECADES?
            v.select_nth_unstable_by(k, f64::total_cmp);
            v[..=k].sort_unstable_by(f64::total_cmp);
            let gap = (0..k)
                .rev()
                .map(|i| (v[i + 1].log10() - v[i].log10(), i))
                .find(|(g, _)| *g > GAP_DECADES);
            if let Some((_, i)) = gap {
                if v[i + 1] > floor.0 {
                    floor = (v[i + 1], FloorRule::Strays);
                }
            }
        }
        if lo < floor.0 {
            rep.floor = Some(floor);
            rep.below_floor = v.iter().filter(|x| **x < floor.0).count();
            lo = floor.0;
        }
    }
    if log {
        let (mut l0, mut l1) = (lo.log10(), hi.log10());
        if l1 - l0 < MIN_RELATIVE_WIDTH {
            let m = (l0 + l1) / 2.0;
            (l0, l1) = (m - 0.5, m + 0.5);
            rep.widened = true;
        }
        let pad = margin.max(0.0) * (l1 - l0);
        rep.lo = 10f64.powf((l0 - pad).max(-307.0));
        rep.hi = 10f64.powf((l1 + pad).min(307.0));
    } else {
        let mag = lo.abs().max(hi.abs());
        if hi - lo <= mag * MIN_RELATIVE_WIDTH || hi - lo <= f64::MIN_POSITIVE {
            let m = lo / 2.0 + hi / 2.0;
            let half = if m == 0.0 {
                1.0
            } else {
                (m.abs() * 0.05).max(f64::MIN_POSITIVE)
            };
            (lo, hi) = (m - half, m + half);
            rep.widened = true;
        }
        let pad = margin.max(0.0) * (hi / 2.0 - lo / 2.0) * 2.0;
        rep.lo = (lo - pad).max(-1.1 * LIMIT);
        rep.hi = (hi + pad).min(1.1 * LIMIT);
    }
    rep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_and_empty_ranges_are_widened() {
        let r = axis_range(&mut [3.0, 3.0], Scale::Linear, None, 0.0);
        assert!(r.widened && r.lo < 3.0 && r.hi > 3.0);
        let r = axis_range(&mut [0.0], Scale::Linear, None, 0.0);
        assert_eq!((r.lo, r.hi), (-1.0, 1.0));
        let r = axis_range(&mut [], Scale::Log, None, 0.1);
        assert!(r.empty && r.lo == 1.0 && r.hi == 10.0);
        let r = axis_range(&mut [1e-300], Scale::Log, None, 0.0);
        assert!(r.widened && r.lo > 0.0 && r.hi > r.lo);
    }

    #[test]
    fn huge_values_are_clamped() {
        let r = axis_range(&mut [-f64::MAX, 0.0, f64::MAX], Scale::Linear, None, 0.05);
        assert_eq!(r.clamped, 2);
        assert!(r.lo.is_finite() && r.hi.is_finite() && (r.hi - r.lo).is_finite());
    }

    #[test]
    fn stray_tiny_values_do_not_stretch_a_log_axis() {
        let mut v: Vec<f64> = (0..1000).map(|i| 1e-3 * (1.0 + f64::from(i))).collect();
        v.push(1e-17);
        let r = axis_range(&mut v, Scale::Log, None, 0.0);
        assert_eq!(r.below_floor, 1);
        let (floor, rule) = r.floor.expect("floor applies");
        assert_eq!(rule, FloorRule::Strays);
        assert!((floor - 1e-3).abs() < 1e-12, "{floor}");
        // Data that genuinely spans many decades keep their range.
        let mut v: Vec<f64> = (0..1000)
            .map(|i| 10f64.powf(-f64::from(i) / 100.0))
            .collect();
        let r = axis_range(&mut v, Scale::Log, None, 0.0);
        assert!(r.floor.is_none() && r.lo < 1.1e-9);
        // Evenly spaced values (a log-time axis) have no gap: the first steps stay.
        let mut v: Vec<f64> = (1..=30_000).map(|k| f64::from(k) * 1e-3).collect();
        let r = axis_range(&mut v, Scale::Log, None, 0.0);
        assert!(r.floor.is_none() && r.lo <= 1e-3 * (1.0 + 1e-12), "{r:?}");
    }

    #[test]
    fn round_off_next_to_order_one_values_stays_below_the_axis() {
        // 30 % of the values are round-off (too many to be strays): at most MAX_DECADES below the top.
        let mut v: Vec<f64> = (0..1000)
            .map(|i| if i < 300 { 1e-16 } else { 0.3 })
            .collect();
        let r = axis_range(&mut v, Scale::Log, None, 0.0);
        assert_eq!(r.floor.map(|f| f.1), Some(FloorRule::DynamicRange));
        assert_eq!(r.below_floor, 300);
        assert!((r.lo / 3e-13 - 1.0).abs() < 1e-9, "{r:?}");
    }

    #[test]
    fn a_stray_huge_value_does_not_squash_a_log_axis() {
        let mut v: Vec<f64> = (1..=1000).map(|k| f64::from(k) * 1e-3).collect();
        v.push(1e300);
        let r = axis_range(&mut v, Scale::Log, None, 0.0);
        assert_eq!((r.ceiling, r.above_ceiling), (Some(1.0), 1));
        assert!(
            r.floor.is_none() && (r.hi - 1.0).abs() < 1e-12 && r.lo <= 1e-3 * (1.0 + 1e-12),
            "{r:?}"
        );
    }

    #[test]
    fn unusable_fixed_ranges_are_replaced() {
        let r = axis_range(&mut [1.0, 2.0], Scale::Log, Some((0.0, 5.0)), 0.0);
        assert!(r.fixed_ignored && !r.fixed && r.lo >= 1.0);
        let r = axis_range(&mut [1.0, 2.0], Scale::Linear, Some((5.0, -5.0)), 0.0);
        assert!(r.fixed && r.lo == -5.0 && r.hi == 5.0);
    }
}
