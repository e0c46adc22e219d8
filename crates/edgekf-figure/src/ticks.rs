//! Tick positions and labels, computed here so that plotters never computes key points (its
//! `compute_f64_key_points` spins forever or panics on some huge ranges).
//!
//! - Linear axes: steps of 1, 2 or 5 × 10ⁿ; labels with the decimals the step needs, no `-0`, a real minus sign
//!   (U+2212), and `m·10ⁿ` when the numbers are large (≥ 10⁶) or small (< 10⁻³).
//! - Log axes: decades labelled `10ⁿ` (Unicode superscripts; `10⁰` too, for one style on the whole axis) with
//!   unlabelled minor ticks at 2…9; many decades are labelled every k-th; a range spanning less than a decade gets
//!   2–5 "nice" mantissa ticks labelled `2·10⁻²`, never `2.5e0`.
//!
//! Every loop here is bounded by a tick budget, whatever the range (ranges are sanitised before, see
//! [`super::range`], but these functions do not rely on it for termination).

/// One tick of an axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Tick {
    /// Position in data units.
    pub value: f64,
    /// Label, or `None` for a minor tick.
    pub label: Option<String>,
}

impl Tick {
    fn major(value: f64, label: String) -> Tick {
        Tick {
            value,
            label: Some(label),
        }
    }
    fn minor(value: f64) -> Tick {
        Tick { value, label: None }
    }
    /// Whether the tick is labelled.
    pub fn is_major(&self) -> bool {
        self.label.is_some()
    }
}

/// Most ticks (major and minor) an axis ever gets.
const MAX_TICKS: usize = 400;

/// The superscript form of an integer: `-12` → `⁻¹²`.
pub fn superscript(n: i32) -> String {
    n.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

/// `10ⁿ`.
pub fn pow10_label(n: i32) -> String {
    format!("10{}", superscript(n))
}

/// Replaces ASCII hyphen-minus by the minus sign U+2212.
fn minus(s: String) -> String {
    match s.strip_prefix('-') {
        Some(rest) => format!("−{rest}"),
        None => s,
    }
}

/// `m·10ⁿ` with at most `decimals` decimals in the mantissa (trailing zeros dropped); `10ⁿ` when the mantissa
/// prints as 1. The exponent comes from Rust's correctly rounded `{:e}` formatting, so 9.999·10² never shows as
/// `10·10²` and 10³⁰⁰ is not `10·10²⁹⁹` (log10 of it is not exact).
pub fn sci_label(v: f64, decimals: usize) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let f = format!("{:.*e}", decimals.min(15), v);
    let (m, e) = f.split_once('e').unwrap_or((f.as_str(), "0"));
    let exp: i32 = e.parse().unwrap_or(0);
    let m = if m.contains('.') {
        m.trim_end_matches('0').trim_end_matches('.')
    } else {
        m
    };
    match m {
        "1" => pow10_label(exp),
        "-1" => format!("−{}", pow10_label(exp)),
        _ => format!("{}·{}", minus(m.to_string()), pow10_label(exp)),
    }
}

/// The nice step (1, 2 or 5 × 10ⁿ) for `span` with at most `n` intervals, and its exponent n.
pub fn nice_step(span: f64, n: usize) -> (f64, i32) {
    let n = n.max(1) as f64;
    let raw = span / n;
    if !(raw.is_finite() && raw > 0.0) {
        return (1.0, 0);
    }
    let e = raw.log10().floor();
    let e = e.clamp(-320.0, 308.0) as i32;
    for (m, k) in [(1.0, 0), (2.0, 0), (5.0, 0), (1.0, 1)] {
        let step = m * 10f64.powi(e + k);
        if step >= raw * (1.0 - 1e-9) && step > 0.0 && step.is_finite() {
            return (step, e + k);
        }
    }
    (10f64.powi(e + 1), e + 1)
}

/// Labels for values on a linear axis with the given step (exponent `e_step`), all in one notation.
pub fn linear_labels(values: &[f64], step: f64, e_step: i32) -> Vec<String> {
    let maxabs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let e_max = if maxabs > 0.0 {
        maxabs.log10().floor() as i32
    } else {
        0
    };
    let sci = maxabs > 0.0 && !(-3..6).contains(&e_max);
    values
        .iter()
        .map(|&v| {
            let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
            if sci {
                if v == 0.0 {
                    return "0".into();
                }
                let e = v.abs().log10().floor() as i32;
                // Decimals in the mantissa so that the step shows (e.g. 1.5·10⁶ for step 5·10⁵).
                let d = (e - e_step).clamp(0, 12) as usize;
                sci_label(v, d)
            } else {
                let d = (-e_step).clamp(0, 15) as usize;
                let s = format!("{v:.d$}");
                // A value that rounds to zero prints as 0, never -0.
                let s = if s
                    .trim_start_matches('-')
                    .chars()
                    .all(|c| c == '0' || c == '.')
                {
                    s.trim_start_matches('-').to_string()
                } else {
                    s
                };
                minus(s)
            }
        })
        .collect()
}

/// Ticks of a linear axis over `[lo, hi]` with at most `max_labels` labels.
pub fn linear_ticks(lo: f64, hi: f64, max_labels: usize) -> Vec<Tick> {
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return Vec::new();
    }
    let n = max_labels.clamp(2, 30);
    let (step, e) = nice_step(hi - lo, n - 1);
    let (k0, k1) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
    if !(k0.is_finite() && k1.is_finite()) || k1 - k0 > MAX_TICKS as f64 || k1 < k0 {
        return vec![Tick::major(lo, linear_labels(&[lo], step, e).remove(0))];
    }
    let values: Vec<f64> = (0..=(k1 - k0) as i64)
        .map(|i| (k0 + i as f64) * step)
        .collect();
    let labels = linear_labels(&values, step, e);
    let mut ticks: Vec<Tick> = values
        .into_iter()
        .zip(labels)
        .map(|(v, l)| Tick::major(v, l))
        .collect();
    // Minor ticks halfway (or at fifths for a step of 1·10ⁿ or 5·10ⁿ…): one unlabelled tick between labels.
    let minor_step = step / 2.0;
    let (m0, m1) = (
        (lo / minor_step - 1e-9).ceil(),
        (hi / minor_step + 1e-9).floor(),
    );
    if m1 - m0 <= MAX_TICKS as f64 {
        for i in 0..=((m1 - m0).max(0.0) as i64) {
            let k = m0 + i as f64;
            if k.rem_euclid(2.0) != 0.0 {
                ticks.push(Tick::minor(k * minor_step));
            }
        }
    }
    ticks.sort_by(|a, b| a.value.total_cmp(&b.value));
    ticks
}

/// Ticks of a log axis over `[lo, hi]` (both > 0) with at most `max_labels` labels; `px_per_decade` decides
/// whether the 2…9 minor ticks fit.
pub fn log_ticks(lo: f64, hi: f64, max_labels: usize, px_per_decade: f64) -> Vec<Tick> {
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    if !(lo > 0.0 && hi.is_finite()) || hi <= lo {
        return Vec::new();
    }
    let (l0, l1) = (lo.log10(), hi.log10());
    // A decade within rounding of an end counts as inside (log10(1e-3) is -2.9999999999999996).
    let (d0, d1) = ((l0 - 1e-9).ceil() as i32, (l1 + 1e-9).floor() as i32);
    let inside = |v: f64| v >= lo * (1.0 - 1e-12) && v <= hi * (1.0 + 1e-12);
    let n_dec = d1 - d0 + 1;
    let max_labels = max_labels.clamp(2, 30);
    if n_dec >= 2 {
        // Label every s-th decade.
        let strides = [1, 2, 3, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000];
        let s = strides
            .iter()
            .copied()
            .find(|&s| (n_dec + s - 1) / s <= max_labels as i32)
            .unwrap_or(1000);
        // Unlabelled decades get a minor tick when they are at least 5 px apart; otherwise every
        // (s/5)-th or (s/2)-th decade does, or none.
        let minor_every = [1, s / 5, s / 2]
            .into_iter()
            .filter(|&m| m >= 1 && s % m == 0)
            .find(|&m| f64::from(m) * px_per_decade >= 5.0 && n_dec / m <= MAX_TICKS as i32);
        let mut ticks = Vec::new();
        for d in d0..=d1 {
            let v = 10f64.powi(d);
            if d.rem_euclid(s) == 0 {
                ticks.push(Tick::major(v, pow10_label(d)));
            } else if minor_every.is_some_and(|m| d.rem_euclid(m) == 0) {
                ticks.push(Tick::minor(v));
            }
        }
        if s == 1 && px_per_decade >= 30.0 && (n_dec + 1) * 8 <= MAX_TICKS as i32 {
            for d in d0 - 1..=d1 {
                for m in 2..=9 {
                    let v = f64::from(m) * 10f64.powi(d);
                    if inside(v) {
                        ticks.push(Tick::minor(v));
                    }
                }
            }
        }
        ticks.sort_by(|a, b| a.value.total_cmp(&b.value));
        return ticks;
    }
    // Less than two decades labelled: nice mantissas.
    let (e0, e1) = (l0.floor() as i32, l1.ceil() as i32);
    let sets: [&[f64]; 4] = [
        &[1.0, 2.0, 5.0],
        &[1.0, 2.0, 3.0, 5.0],
        &[1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.0],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
    ];
    let want_max = max_labels.min(5);
    for set in sets {
        let vals: Vec<(f64, f64, i32)> = (e0..=e1)
            .flat_map(|e| set.iter().map(move |&m| (m * 10f64.powi(e), m, e)))
            .filter(|(v, _, _)| inside(*v))
            .collect();
        if vals.len() >= 2 && vals.len() <= want_max.max(2) {
            let mut ticks: Vec<Tick> = vals
                .iter()
                .map(|&(v, _, _)| Tick::major(v, sci_label(v, 1)))
                .collect();
            for e in e0..=e1 {
                for m in 1..=9 {
                    let v = f64::from(m) * 10f64.powi(e);
                    if inside(v) && !vals.iter().any(|t| (t.0 - v).abs() <= v * 1e-12) {
                        ticks.push(Tick::minor(v));
                    }
                }
            }
            ticks.sort_by(|a, b| a.value.total_cmp(&b.value));
            return ticks;
        }
        if vals.len() > want_max {
            break;
        }
    }
    // Narrower than one mantissa step: linear nice ticks, labelled m·10ⁿ.
    for intervals in 2..=6 {
        let (step, e_step) = nice_step(hi - lo, intervals);
        let (k0, k1) = ((lo / step - 1e-9).ceil(), (hi / step + 1e-9).floor());
        if !(k0.is_finite() && k1.is_finite()) || k1 < k0 || k1 - k0 > MAX_TICKS as f64 {
            continue;
        }
        if k1 - k0 + 1.0 >= 2.0 || intervals == 6 {
            return (0..=(k1 - k0) as i64)
                .map(|i| {
                    let v = (k0 + i as f64) * step;
                    let e = v.log10().floor() as i32;
                    Tick::major(v, sci_label(v, (e - e_step).clamp(0, 12) as usize))
                })
                .collect();
        }
    }
    Vec::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(t: &[Tick]) -> Vec<&str> {
        t.iter().filter_map(|t| t.label.as_deref()).collect()
    }

    #[test]
    fn superscripts() {
        assert_eq!(pow10_label(-2), "10⁻²");
        assert_eq!(pow10_label(0), "10⁰");
        assert_eq!(pow10_label(13), "10¹³");
        assert_eq!(sci_label(2e-2, 0), "2·10⁻²");
        assert_eq!(sci_label(1.5e6, 1), "1.5·10⁶");
        assert_eq!(sci_label(1.5e6, 3), "1.5·10⁶");
        assert_eq!(sci_label(-3e-5, 0), "−3·10⁻⁵");
        assert_eq!(sci_label(9.9999e2, 1), "10³");
        assert_eq!(sci_label(1e300, 2), "10³⁰⁰");
    }

    #[test]
    fn linear_steps_are_nice_and_zero_is_never_negative() {
        let t = linear_ticks(-0.35, 0.52, 10);
        assert_eq!(
            labels(&t),
            ["−0.3", "−0.2", "−0.1", "0.0", "0.1", "0.2", "0.3", "0.4", "0.5"]
        );
        let t = linear_ticks(0.0, 30.0, 7);
        assert_eq!(labels(&t), ["0", "5", "10", "15", "20", "25", "30"]);
        for (lo, hi) in [(-1e-17, 2.0), (-0.3, 0.3), (-2.0, 1e-16), (-30.0, 30.0)] {
            let t = linear_ticks(lo, hi, 7);
            let l = labels(&t);
            assert!(l.iter().all(|l| !l.starts_with('-')), "{l:?}");
            assert!(
                !l.iter().any(
                    |l| l.starts_with("−0") && l.trim_start_matches(['−', '0', '.']).is_empty()
                ),
                "{l:?}"
            );
        }
        for (lo, hi) in [(0.0, 1.0), (-3.0, 7.0), (1e-9, 3e-9), (12345.0, 12399.0)] {
            let t = linear_ticks(lo, hi, 6);
            let v: Vec<f64> = t.iter().filter(|t| t.is_major()).map(|t| t.value).collect();
            assert!(v.len() >= 2, "{lo}..{hi}: {v:?}");
            let step = v[1] - v[0];
            let m = step / 10f64.powf(step.log10().floor());
            assert!(
                [1.0, 2.0, 5.0, 10.0].iter().any(|n| (m - n).abs() < 1e-6),
                "step {step}"
            );
        }
    }

    #[test]
    fn large_and_small_linear_numbers_use_powers_of_ten() {
        let t = linear_ticks(0.0, 3e6, 4);
        assert_eq!(labels(&t), ["0", "10⁶", "2·10⁶", "3·10⁶"]);
        let t = linear_ticks(0.0, 2e-4, 3);
        assert_eq!(labels(&t), ["0", "10⁻⁴", "2·10⁻⁴"]);
        let t = linear_ticks(-1e300, 1e300, 5);
        assert!(labels(&t).contains(&"0"));
        assert!(
            labels(&t).iter().any(|l| l.contains("10³⁰⁰")),
            "{:?}",
            labels(&t)
        );
    }

    #[test]
    fn log_decades_labelled_with_superscripts() {
        let t = log_ticks(1e-3, 10.0, 10, 80.0);
        assert_eq!(labels(&t), ["10⁻³", "10⁻²", "10⁻¹", "10⁰", "10¹"]);
        // 2…9 minor ticks, unlabelled.
        assert!(t
            .iter()
            .any(|t| !t.is_major() && (t.value - 0.05).abs() < 1e-12));
        // No 1.6e-2 style values among the labelled ticks.
        assert!(t.iter().filter(|t| t.is_major()).all(|t| {
            let m = t.value / 10f64.powf(t.value.log10().floor());
            (m - 1.0).abs() < 1e-9
        }));
    }

    #[test]
    fn many_decades_are_thinned() {
        let t = log_ticks(1e-300, 1e300, 8, 1.0);
        let l = labels(&t);
        assert!(l.len() <= 8 && l.len() >= 2, "{l:?}");
        assert!(l.contains(&"10⁰"));
        assert!(t.len() <= MAX_TICKS + 1);
    }

    #[test]
    fn narrow_log_ranges_get_mantissa_ticks() {
        let t = log_ticks(1.5e-2, 6e-2, 8, 200.0);
        assert_eq!(labels(&t), ["2·10⁻²", "5·10⁻²"]);
        let t = log_ticks(0.6, 3.0, 8, 200.0);
        assert_eq!(labels(&t), ["10⁰", "2·10⁰"]);
        let t = log_ticks(2.1e-2, 2.9e-2, 8, 200.0);
        let l = labels(&t);
        assert!((2..=5).contains(&l.len()), "{l:?}");
        assert!(
            l.iter().all(|s| s.contains("·10⁻²") && !s.contains('e')),
            "{l:?}"
        );
    }
}
