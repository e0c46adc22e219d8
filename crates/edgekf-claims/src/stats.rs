//! Estimates with standard errors, from independent units (Monte Carlo runs, or seeds).
//!
//! Every standard error here comes from the spread of independent units, never from a model:
//!
//! - **mean of per-unit values** ([`mean`]): `s / √n`, `s` the sample standard deviation
//!   (ddof = 1) of the `n` unit values;
//! - **ratio of paired means** ([`ratio`]): `ρ = Σa / Σb` over the same units (the estimators of
//!   one run share its draws: common random numbers), with the delta-method standard error
//!   `sd(a_u − ρ b_u) / (√n · b̄)`, which is what pairing buys: the common part of `a` and `b`
//!   cancels in `a_u − ρ b_u`;
//! - **any other smooth statistic of the units** ([`jackknife`]): the leave-one-out jackknife,
//!   `SE² = (n − 1)/n Σ (θ₋ᵤ − θ̄₋)²`;
//! - **independent estimates combined** ([`quotient`]): relative errors added in quadrature.
//!
//! A quantity that is the same in every unit bit for bit (the covariance trace of a filter
//! whose gain does not depend on the data) is exact: its standard error is 0, and a comparison
//! of such quantities is exact too.

/// A value with its standard error (`se = 0`: exact; NaN: no error available, e.g. one seed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Its standard error.
    pub se: f64,
}

impl Estimate {
    /// An exact value (standard error 0).
    pub fn exact(value: f64) -> Self {
        Self { value, se: 0.0 }
    }

    /// A value without an error estimate.
    pub fn unknown(value: f64) -> Self {
        Self {
            value,
            se: f64::NAN,
        }
    }
}

/// Whether every value is the same, bit for bit.
pub fn all_equal(v: &[f64]) -> bool {
    v.iter().all(|x| x.to_bits() == v[0].to_bits())
}

/// Sample standard deviation (ddof = 1).
fn sd(v: &[f64], mean: f64) -> f64 {
    let n = v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
}

/// The mean of independent unit values and its standard error `s / √n`; identical values are
/// exact (SE 0); one unit has no error (NaN).
pub fn mean(v: &[f64]) -> Estimate {
    let n = v.len();
    if n == 0 {
        return Estimate::unknown(f64::NAN);
    }
    if all_equal(v) {
        return if n > 1 {
            Estimate::exact(v[0])
        } else {
            Estimate::unknown(v[0])
        };
    }
    let m = v.iter().sum::<f64>() / n as f64;
    Estimate {
        value: m,
        se: sd(v, m) / (n as f64).sqrt(),
    }
}

/// The ratio of the means of paired unit values `a_u`, `b_u` with its delta-method standard
/// error `sd(a_u − ρ b_u) / (√n · b̄)`. When both are the same in every unit the ratio is exact.
pub fn ratio(a: &[f64], b: &[f64]) -> Estimate {
    assert_eq!(a.len(), b.len(), "paired values");
    let n = a.len();
    if n == 0 {
        return Estimate::unknown(f64::NAN);
    }
    let (ma, mb) = (
        a.iter().sum::<f64>() / n as f64,
        b.iter().sum::<f64>() / n as f64,
    );
    if all_equal(a) && all_equal(b) {
        let r = a[0] / b[0];
        return if n > 1 {
            Estimate::exact(r)
        } else {
            Estimate::unknown(r)
        };
    }
    let rho = ma / mb;
    if n == 1 {
        return Estimate::unknown(rho);
    }
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - rho * y).collect();
    let md = d.iter().sum::<f64>() / n as f64;
    Estimate {
        value: rho,
        se: sd(&d, md) / ((n as f64).sqrt() * mb.abs()),
    }
}

/// The leave-one-out jackknife of a statistic `f` of `n` independent units: `f(all)` with
/// `SE² = (n − 1)/n Σ_u (f₋ᵤ − mean f₋)²`, where `f` receives the indices of the units to use.
/// When every leave-one-out value equals the full one bit for bit, the value is exact.
pub fn jackknife(n: usize, f: impl Fn(&[usize]) -> f64) -> Estimate {
    let all: Vec<usize> = (0..n).collect();
    let full = f(&all);
    if n < 2 {
        return Estimate::unknown(full);
    }
    let mut loo = Vec::with_capacity(n);
    let mut idx: Vec<usize> = Vec::with_capacity(n - 1);
    for u in 0..n {
        idx.clear();
        idx.extend((0..n).filter(|&v| v != u));
        loo.push(f(&idx));
    }
    if loo.iter().all(|x| x.to_bits() == full.to_bits()) {
        return Estimate::exact(full);
    }
    let m = loo.iter().sum::<f64>() / n as f64;
    let ss: f64 = loo.iter().map(|x| (x - m).powi(2)).sum();
    Estimate {
        value: full,
        se: ((n as f64 - 1.0) / n as f64 * ss).sqrt(),
    }
}

/// `a / b` for independent estimates: relative errors in quadrature.
pub fn quotient(a: Estimate, b: Estimate) -> Estimate {
    let v = a.value / b.value;
    let rel = ((a.se / a.value).powi(2) + (b.se / b.value).powi(2)).sqrt();
    Estimate {
        value: v,
        se: if a.se == 0.0 && b.se == 0.0 {
            0.0
        } else {
            v.abs() * rel
        },
    }
}

/// `a − b` for independent estimates.
pub fn difference(a: Estimate, b: Estimate) -> Estimate {
    Estimate {
        value: a.value - b.value,
        se: (a.se.powi(2) + b.se.powi(2)).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_exactness() {
        let e = mean(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(e.value, 2.5);
        assert!((e.se - (5.0f64 / 3.0).sqrt() / 2.0).abs() < 1e-15);
        assert_eq!(mean(&[0.3; 5]), Estimate::exact(0.3));
        assert!(mean(&[0.3]).se.is_nan());
    }

    /// The delta-method SE of a ratio of paired means equals the jackknife's to O(1/n).
    #[test]
    fn paired_ratio_matches_the_jackknife() {
        // A common factor c_u (shared draws) and small independent parts.
        let n = 200;
        let c: Vec<f64> = (0..n)
            .map(|u| 1.0 + ((u * 37 % 101) as f64) / 50.0)
            .collect();
        let a: Vec<f64> = (0..n)
            .map(|u| 0.9 * c[u] + ((u * 53 % 97) as f64 - 48.0) * 1e-3)
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|u| c[u] + ((u * 29 % 89) as f64 - 44.0) * 1e-3)
            .collect();
        let r = ratio(&a, &b);
        let j = jackknife(n, |idx| {
            idx.iter().map(|&u| a[u]).sum::<f64>() / idx.iter().map(|&u| b[u]).sum::<f64>()
        });
        assert!((r.value - j.value).abs() < 1e-15);
        assert!((r.se / j.se - 1.0).abs() < 0.05, "{} vs {}", r.se, j.se);
        // Pairing: far smaller than the unpaired error of either mean.
        assert!(r.se < 0.1 * mean(&a).se / mean(&b).value);
        // Exact when both are constant.
        assert_eq!(ratio(&[2.0; 3], &[4.0; 3]), Estimate::exact(0.5));
    }

    #[test]
    fn quotient_adds_relative_errors() {
        let q = quotient(
            Estimate {
                value: 2.0,
                se: 0.02,
            },
            Estimate {
                value: 4.0,
                se: 0.04,
            },
        );
        assert_eq!(q.value, 0.5);
        assert!((q.se - 0.5 * 2f64.sqrt() * 0.01).abs() < 1e-15);
        assert_eq!(
            quotient(Estimate::exact(1.0), Estimate::exact(4.0)),
            Estimate::exact(0.25)
        );
    }
}
