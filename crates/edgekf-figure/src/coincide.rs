//! Curves that coincide: equal within a relative tolerance over the plotted range, so that one would hide the
//! other. They are drawn with distinct dash patterns and markers, and the legend says so.
//!
//! Two curves coincide when, at every x both cover (each curve's points compared against the other's linear
//! interpolant), `|y₁ − y₂| ≤ tol · s`, with `s = max(|y₁|, |y₂|)` on a log axis (a ratio) and `s` the plotted
//! y span on a linear axis (a share of the figure's height). Their common x range must cover at least 90 % of
//! the wider one's. Coincidence is grouped transitively.

use super::Scale;

/// Curves found equal within the tolerance; part of the [`super::PanelReport`].
#[derive(Clone, Debug, PartialEq)]
pub struct CoincideGroup {
    /// Indices of the curves in the panel.
    pub members: Vec<usize>,
    /// Their labels.
    pub labels: Vec<String>,
    /// The tolerance used (relative).
    pub tolerance: f64,
    /// The largest deviation found between members, in the same relative units.
    pub max_deviation: f64,
}

/// One curve's finite points, x ascending (only such curves are compared).
pub(crate) struct Series<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
}

fn sorted(x: &[f64]) -> bool {
    x.windows(2).all(|w| w[0] <= w[1])
}

/// Linear interpolation of `(x, y)` at `t` (x ascending), `None` outside or next to a non-finite value.
pub(crate) fn interp(x: &[f64], y: &[f64], t: f64) -> Option<f64> {
    let i = x.partition_point(|v| *v < t);
    if i < x.len() && x[i] == t {
        return y[i].is_finite().then_some(y[i]);
    }
    if i == 0 || i >= x.len() {
        return None;
    }
    let (x0, x1, y0, y1) = (x[i - 1], x[i], y[i - 1], y[i]);
    if !(y0.is_finite() && y1.is_finite()) || x1 <= x0 {
        return None;
    }
    Some(y0 + (y1 - y0) * (t - x0) / (x1 - x0))
}

/// Largest relative deviation of `b` from `a` over `a`'s points, or `None` when they are not comparable.
fn deviation(a: &Series, b: &Series, scale: Scale, span: f64) -> Option<(f64, usize)> {
    let (mut worst, mut n) = (0.0f64, 0usize);
    let same_grid = a.x.len() == b.x.len() && a.x.iter().zip(b.x).all(|(p, q)| p == q);
    for (i, (&t, &ya)) in a.x.iter().zip(a.y).enumerate() {
        if !(t.is_finite() && ya.is_finite()) {
            continue;
        }
        let yb = if same_grid {
            let v = b.y[i];
            if v.is_finite() {
                v
            } else {
                continue;
            }
        } else {
            match interp(b.x, b.y, t) {
                Some(v) => v,
                None => continue,
            }
        };
        let s = match scale {
            Scale::Log => ya.abs().max(yb.abs()),
            Scale::Linear => span,
        };
        let d = (ya - yb).abs();
        let r = if d == 0.0 {
            0.0
        } else if s > 0.0 {
            d / s
        } else {
            f64::INFINITY
        };
        worst = worst.max(r);
        n += 1;
    }
    (n >= 2).then_some((worst, n))
}

/// Groups of coinciding curves among `curves` (`None` entries are not compared).
pub(crate) fn find(
    curves: &[Option<Series>],
    labels: &[String],
    tol: f64,
    scale: Scale,
    span: f64,
) -> Vec<CoincideGroup> {
    let n = curves.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let mut dev = vec![0.0f64; n];
    for i in 0..n {
        for j in 0..i {
            let (Some(a), Some(b)) = (&curves[i], &curves[j]) else {
                continue;
            };
            if !(sorted(a.x) && sorted(b.x)) || a.x.is_empty() || b.x.is_empty() {
                continue;
            }
            let (a0, a1) = (a.x[0], a.x[a.x.len() - 1]);
            let (b0, b1) = (b.x[0], b.x[b.x.len() - 1]);
            let common = a1.min(b1) - a0.max(b0);
            let union = a1.max(b1) - a0.min(b0);
            if common.is_nan() || common < 0.9 * union {
                continue;
            }
            let (Some((d1, _)), Some((d2, _))) =
                (deviation(a, b, scale, span), deviation(b, a, scale, span))
            else {
                continue;
            };
            let d = d1.max(d2);
            if d <= tol {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
                dev[i] = dev[i].max(d);
                dev[j] = dev[j].max(d);
            }
        }
    }
    let mut groups: Vec<CoincideGroup> = Vec::new();
    let mut seen: Vec<Option<usize>> = vec![None; n];
    for i in 0..n {
        let r = root(&mut parent, i);
        match seen[r] {
            Some(g) => {
                groups[g].members.push(i);
                groups[g].labels.push(labels[i].clone());
                groups[g].max_deviation = groups[g].max_deviation.max(dev[i]);
            }
            None => {
                seen[r] = Some(groups.len());
                groups.push(CoincideGroup {
                    members: vec![i],
                    labels: vec![labels[i].clone()],
                    tolerance: tol,
                    max_deviation: dev[i],
                });
            }
        }
    }
    groups.retain(|g| g.members.len() >= 2);
    groups
}

/// A short name for a group of labels: the common prefix, then "first … last" of the rest
/// (`"rkf-ar P_fail = 0 … 1"`), or the labels joined by commas.
pub fn group_name(labels: &[String]) -> String {
    if labels.is_empty() {
        return String::new();
    }
    let first: Vec<char> = labels[0].chars().collect();
    let mut k = first.len();
    for l in &labels[1..] {
        k = k.min(l.chars().zip(&first).take_while(|(a, b)| a == *b).count());
    }
    // Cut the prefix at a word boundary so that "0.25" and "0.5" do not share "0.".
    let prefix: String = first[..k].iter().collect();
    let cut = prefix.rfind([' ', '=', ':', '(']).map_or(0, |p| p + 1);
    let prefix = &prefix[..cut];
    if prefix.trim().is_empty() || labels.len() <= 2 {
        return labels.join(", ");
    }
    let rest = |l: &String| l[prefix.len()..].trim().to_string();
    format!(
        "{prefix}{} … {}",
        rest(&labels[0]),
        rest(&labels[labels.len() - 1])
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s<'a>(x: &'a [f64], y: &'a [f64]) -> Option<Series<'a>> {
        Some(Series { x, y })
    }

    #[test]
    fn equal_curves_are_found_and_distinct_ones_are_not() {
        let x: Vec<f64> = (0..500).map(f64::from).collect();
        let a: Vec<f64> = x.iter().map(|t| (-t / 50.0).exp()).collect();
        let b: Vec<f64> = a.iter().map(|v| v * (1.0 + 5e-4)).collect();
        let c: Vec<f64> = a.iter().map(|v| v * 1.01).collect();
        let labels: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let g = find(
            &[s(&x, &a), s(&x, &b), s(&x, &c)],
            &labels,
            1e-3,
            Scale::Log,
            1.0,
        );
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].members, vec![0, 1]);
        assert!(g[0].max_deviation > 4e-4 && g[0].max_deviation < 6e-4);
    }

    #[test]
    fn different_grids_are_interpolated() {
        let x1: Vec<f64> = (0..=100).map(|i| f64::from(i) / 10.0).collect();
        let x2: Vec<f64> = (0..=40).map(|i| f64::from(i) / 4.0).collect();
        let y1: Vec<f64> = x1.iter().map(|t| 2.0 * t + 1.0).collect();
        let y2: Vec<f64> = x2.iter().map(|t| 2.0 * t + 1.0).collect();
        let labels = vec!["p".to_string(), "q".to_string()];
        let g = find(
            &[s(&x1, &y1), s(&x2, &y2)],
            &labels,
            1e-3,
            Scale::Linear,
            21.0,
        );
        assert_eq!(g.len(), 1);
        // A curve over a tenth of the range does not count as coinciding.
        let g = find(
            &[s(&x1, &y1), s(&x2[..5], &y2[..5])],
            &labels,
            1e-3,
            Scale::Linear,
            21.0,
        );
        assert!(g.is_empty());
    }

    #[test]
    fn group_names() {
        let l: Vec<String> = ["0", "0.25", "0.5", "0.75", "1"]
            .iter()
            .map(|p| format!("rkf-ar P_fail = {p}"))
            .collect();
        assert_eq!(group_name(&l), "rkf-ar P_fail = 0 … 1");
        assert_eq!(group_name(&["mle".into(), "mmse".into()]), "mle, mmse");
    }
}
