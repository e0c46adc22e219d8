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
/// of a shared-gain filter) the mean is that value exactly and the standard deviation 0.
pub fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    if v.iter().all(|x| x.to_bits() == v[0].to_bits()) {
        return (v[0], if n > 1 { 0.0 } else { f64::NAN });
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    let std = if n > 1 {
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
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
    }
}
