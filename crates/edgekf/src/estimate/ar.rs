//! Autoregressive models of a neighbour's input (thesis §6.1, eq. 6.5) and their Yule–Walker fit.
//!
//! Each coordinate `d` of an agent's input is modelled as a scalar AR(p) process
//! `u_t = Σ_l a_l u_{t−l} + n_t`, `n_t ~ N(0, σ²_n)` (6.5 with elementwise coefficients `a_l`).
//! Everything here is per coordinate; a model is the `p × D` coefficients and the `D` innovation
//! variances.
//!
//! # Normalisation (a slip of the thesis)
//! Thesis (6.9) writes the AR(1) autocorrelation as `R_u(τ) = diag(a₁)^|τ|`, i.e. normalised to
//! `R_u(0) = I`, and (6.17) inherits that (`W₁ = diag(a₁)(I + Σ_û)⁻¹`). For an AR(1) process the
//! autocovariance is `r(τ) = a^|τ| σ²_n / (1 − a²)`; with noisy observations the normalisation does
//! not cancel, so we use the real autocovariance `r(0)` implied by the fitted `(a, σ²_n)`
//! ([`ArModel::autocovariance`]). Fitting by Yule–Walker uses the sample autocovariance (not the
//! autocorrelation), so `σ²_n` comes out in the input's own units, (m/s)².

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// An AR(p) model, per coordinate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArModel {
    /// `coeffs[l][d]`: coefficient of lag `l + 1` for coordinate `d` (thesis `a_{l+1}`).
    pub coeffs: Vec<Vec<f64>>,
    /// Innovation variance `σ²_n` per coordinate (the diagonal of thesis `Σ_n`).
    pub noise_var: Vec<f64>,
}

/// The largest AR order a scenario may give: the check solves a (p + 1) × (p + 1) system per
/// coordinate and the filters sum p lags per edge and step, so an order of thousands (a slip)
/// would stall the check for a minute; an input model needs a handful of lags.
pub const MAX_ORDER: usize = 100;

impl ArModel {
    /// Order p.
    pub fn order(&self) -> usize {
        self.coeffs.len()
    }

    /// Checks dimensions, finiteness and stationarity.
    ///
    /// # Errors
    /// A message naming the problem.
    pub fn check(&self, dim: usize) -> Result<(), String> {
        if self.coeffs.is_empty() {
            return Err("`coeffs` needs at least one lag".into());
        }
        if self.order() > MAX_ORDER {
            return Err(format!(
                "`coeffs` has {} lags; an AR model here has at most {MAX_ORDER}",
                self.order()
            ));
        }
        for (l, a) in self.coeffs.iter().enumerate() {
            if a.len() != dim || a.iter().any(|v| !v.is_finite()) {
                return Err(format!(
                    "`coeffs[{l}]` must have dim = {dim} finite entries"
                ));
            }
        }
        if self.noise_var.len() != dim
            || self.noise_var.iter().any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err(format!(
                "`noise_var` must have dim = {dim} finite entries ≥ 0"
            ));
        }
        for d in 0..dim {
            let r = self.autocovariance_1d(d, self.order());
            if r.as_ref()
                .is_none_or(|r| !(r[0] > 0.0 || self.noise_var[d] == 0.0))
            {
                return Err(format!("the AR model of coordinate {d} is not stationary"));
            }
        }
        Ok(())
    }

    /// Autocovariance `r_d(τ)`, τ = 0..=max_lag, of coordinate `d`: solves
    /// `r(τ) − Σ_l a_l r(|τ − l|) = σ² δ(τ)` for τ = 0..=p, then extends by the recursion.
    /// `None` for a non-stationary model.
    pub fn autocovariance_1d(&self, d: usize, max_lag: usize) -> Option<Vec<f64>> {
        let p = self.order();
        let mut m = DMatrix::<f64>::identity(p + 1, p + 1);
        for t in 0..=p {
            for l in 1..=p {
                let lag = t.abs_diff(l);
                m[(t, lag)] -= self.coeffs[l - 1][d];
            }
        }
        let mut rhs = DVector::zeros(p + 1);
        rhs[0] = self.noise_var[d];
        let r = m.lu().solve(&rhs)?;
        let mut out: Vec<f64> = r.iter().copied().collect();
        for t in p + 1..=max_lag {
            let v = (1..=p).map(|l| self.coeffs[l - 1][d] * out[t - l]).sum();
            out.push(v);
        }
        out.truncate(max_lag + 1);
        if out[0] < 0.0 || out.iter().any(|v| !v.is_finite()) {
            return None;
        }
        Some(out)
    }

    /// `r(τ)` for every coordinate: `autocovariance(max_lag)[d][τ]`.
    ///
    /// # Panics
    /// For a non-stationary model ([`ArModel::check`] rejects those).
    pub fn autocovariance(&self, dim: usize, max_lag: usize) -> Vec<Vec<f64>> {
        (0..dim)
            .map(|d| {
                self.autocovariance_1d(d, max_lag)
                    .expect("checked stationary")
            })
            .collect()
    }
}

/// Yule–Walker estimate of a scalar AR(p) model from the autocovariance `r(0..=p)`
/// (Levinson–Durbin recursion): returns `(a_1..a_p, σ²_n)`, or `None` if `r(0) ≤ 0`.
pub fn yule_walker(r: &[f64]) -> Option<(Vec<f64>, f64)> {
    let p = r.len().checked_sub(1)?;
    if r[0] <= 0.0 {
        return None;
    }
    let mut a = vec![0.0; p];
    let mut err = r[0];
    for k in 0..p {
        let mut acc = r[k + 1];
        for l in 0..k {
            acc -= a[l] * r[k - l];
        }
        let kappa = acc / err;
        let prev = a.clone();
        a[k] = kappa;
        for l in 0..k {
            a[l] = prev[l] - kappa * prev[k - 1 - l];
        }
        err *= 1.0 - kappa * kappa;
    }
    Some((a, err))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn autocovariance_of_ar1_is_closed_form() {
        let m = ArModel {
            coeffs: vec![vec![0.8, -0.5]],
            noise_var: vec![2.0, 1.0],
        };
        m.check(2).unwrap();
        let r = m.autocovariance(2, 3);
        for (d, (a, s)) in [(0.8f64, 2.0), (-0.5f64, 1.0)].iter().enumerate() {
            for t in 0..=3 {
                let want = a.powi(t as i32) * s / (1.0 - a * a);
                assert!((r[d][t] - want).abs() < 1e-12, "{d} {t}");
            }
        }
        assert!(ArModel {
            coeffs: vec![vec![1.2]],
            noise_var: vec![1.0]
        }
        .check(1)
        .is_err());
    }

    /// Yule–Walker recovers the coefficients of a synthetic AR(2) process within sampling error:
    /// for n samples the coefficient estimates have standard error ≈ √((1 − a₂²)/n) ≈ 0.003 here
    /// (asymptotic AR(2) theory); 5 standard errors bound the check.
    #[test]
    fn yule_walker_recovers_a_synthetic_ar2() {
        let (a1, a2, s2): (f64, f64, f64) = (0.6, -0.3, 0.5);
        let n = 100_000;
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
        let mut x = vec![0.0; n + 200];
        for t in 2..x.len() {
            let e: f64 = rng.sample(rand_distr::StandardNormal);
            x[t] = a1 * x[t - 1] + a2 * x[t - 2] + s2.sqrt() * e;
        }
        let x = &x[200..];
        let r: Vec<f64> = (0..=2)
            .map(|l| x[l..].iter().zip(x).map(|(a, b)| a * b).sum::<f64>() / n as f64)
            .collect();
        let (a, v) = yule_walker(&r).unwrap();
        let se = ((1.0 - a2 * a2) / n as f64).sqrt();
        assert!(
            (a[0] - a1).abs() < 5.0 * se && (a[1] - a2).abs() < 5.0 * se,
            "{a:?}"
        );
        assert!((v - s2).abs() < 5.0 * s2 * (2.0 / n as f64).sqrt(), "{v}");
        // Round trip: the model's own autocovariance gives back the model exactly.
        let m = ArModel {
            coeffs: vec![vec![a1], vec![a2]],
            noise_var: vec![s2],
        };
        let (b, w) = yule_walker(&m.autocovariance_1d(0, 2).unwrap()).unwrap();
        assert!((b[0] - a1).abs() < 1e-12 && (b[1] - a2).abs() < 1e-12 && (w - s2).abs() < 1e-12);
    }
}
