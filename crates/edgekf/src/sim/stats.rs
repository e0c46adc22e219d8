//! Statistics across Monte Carlo runs, reduced in run order so that any split of the runs
//! (threads, shards) gives the same bits.

/// Mean and standard deviation (ddof = 1) across runs at each reported step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Means.
    pub mean: Vec<f64>,
    /// Standard deviations (NaN for a single run; 0 when every run has the same value).
    pub std: Vec<f64>,
}

/// Mean and standard deviation (ddof = 1) of one reported step's per-run values, summed in run
/// order. When every run holds the same value (a deterministic quantity, such as the covariance
/// of a shared-gain filter) the mean is that value exactly and the standard deviation 0. NaN
/// values (a quantity undefined in that run, see [`super::metrics::Metric::partial`]) are left
/// out; with none left both are NaN.
pub fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.iter().any(|x| x.is_nan()) {
        let mut n = 0usize;
        let mut sum = 0.0;
        for x in v.iter().filter(|x| !x.is_nan()) {
            sum += x;
            n += 1;
        }
        if n == 0 {
            return (f64::NAN, f64::NAN);
        }
        let mean = sum / n as f64;
        let std = if n > 1 {
            (v.iter()
                .filter(|x| !x.is_nan())
                .map(|x| (x - mean).powi(2))
                .sum::<f64>()
                / (n - 1) as f64)
                .sqrt()
        } else {
            f64::NAN
        };
        return (mean, std);
    }
    let n = v.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    if v.iter().all(|x| x.to_bits() == v[0].to_bits()) {
        return (v[0], if n > 1 { 0.0 } else { f64::NAN });
    }
    let mut mean = v.iter().sum::<f64>() / n as f64;
    if mean.is_infinite() && v.iter().all(|x| x.is_finite()) {
        // The sum of finite values overflowed: average the scaled values instead.
        mean = v.iter().map(|x| x / n as f64).sum::<f64>();
    }
    let std = if n > 1 {
        let ss = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        if ss.is_finite() || !mean.is_finite() {
            (ss / (n - 1) as f64).sqrt()
        } else {
            // The squares of finite deviations overflowed: scale by the largest deviation.
            let scale = v.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max);
            let s = v.iter().map(|x| ((x - mean) / scale).powi(2)).sum::<f64>();
            scale * (s / (n - 1) as f64).sqrt()
        }
    } else {
        f64::NAN
    };
    (mean, std)
}

impl Series {
    /// The series of per-run values laid out `[report · runs + run]`, over the first `reports`
    /// reported steps.
    pub fn of(values: &[f64], runs: usize, reports: usize) -> Self {
        let mut s = Series {
            mean: Vec::with_capacity(reports),
            std: Vec::with_capacity(reports),
        };
        for k in 0..reports {
            let (m, d) = mean_std(&values[k * runs..(k + 1) * runs]);
            s.mean.push(m);
            s.std.push(d);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_values_are_exact_and_otherwise_ddof_one() {
        let x = 0.1 + 0.2;
        assert_eq!(mean_std(&[x; 7]), (x, 0.0));
        assert!(mean_std(&[x]).1.is_nan());
        let (m, s) = mean_std(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        // Undefined runs are left out.
        assert_eq!(mean_std(&[1.0, f64::NAN, 2.0, 3.0, 4.0]), (m, s));
        assert!(mean_std(&[f64::NAN, f64::NAN]).0.is_nan());
    }

    /// Finite values whose sum or squared deviations overflow still have a finite mean and std
    /// (the whole-program fuzz found `inf` stds of finite 1e292 covariance traces in metrics.csv).
    #[test]
    fn huge_finite_values_have_finite_statistics() {
        let (m, s) = mean_std(&[3e292, 1e292]);
        assert!(
            (m - 2e292).abs() < 1e278 && (s - 2f64.sqrt() * 1e292).abs() < 1e278,
            "{m} {s}"
        );
        let (m, s) = mean_std(&[1.5e308, 1.7e308, 1.6e308]);
        assert!(
            (m - 1.6e308).abs() < 1e294 && (s - 1e307).abs() < 1e294,
            "{m} {s}"
        );
        // Unchanged bits for ordinary values.
        let v = [0.1, 0.7, 0.25];
        let m = v.iter().sum::<f64>() / 3.0;
        let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 2.0).sqrt();
        assert_eq!(mean_std(&v), (m, s));
    }
}
