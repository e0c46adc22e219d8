//! Theorem 1 of Li & Rajan (2026) on a scenario's nominal graph: the coefficients of the bound
//! `E[ψ_i,k] ≤ c_i,k E[δ_k] + b_i,k` (20a–b), averaged over the agents.

use crate::by_dim;
use crate::estimate::ral::{theorem1_coefficients, LocalGeometry, RalOptions, Vector};

use super::Scenario;

impl Scenario {
    /// Theorem 1's `(c̄, b̄)`: `c_i`, `b_i` (20a–b) of every agent on the nominal graph with all
    /// its neighbours observed, averaged over the agents with a feasible RAL; `tr R` is that of
    /// the mean of `samples` measurements. `None` when no agent has a feasible RAL.
    pub fn theorem1_means(&self, samples: usize) -> Option<(f64, f64)> {
        let fw = self.framework();
        let g = fw.graph();
        let n = fw.agents();
        let trace_r = self.model().mean_cov(samples).first()?.trace();
        by_dim!(fw.dim(), D => {
            let cfg: Vec<Vector<D>> = (0..n)
                .map(|i| Vector::<D>::from_fn(|a, _| fw.point(i)[a]))
                .collect();
            let opts = RalOptions::default();
            let geo: Vec<Option<LocalGeometry<D>>> = (0..n)
                .map(|i| {
                    let nb: Vec<usize> = g.neighbours(i).collect();
                    LocalGeometry::new(&cfg, i, &nb, &opts).ok()
                })
                .collect();
            let (mut cs, mut bs, mut k) = (0.0, 0.0, 0usize);
            for i in 0..n {
                let Some(own) = &geo[i] else { continue };
                let nbs: Vec<&LocalGeometry<D>> =
                    g.neighbours(i).filter_map(|j| geo[j].as_ref()).collect();
                if let Some((c, b)) = theorem1_coefficients(n, own, &nbs, trace_r) {
                    cs += c;
                    bs += b;
                    k += 1;
                }
            }
            (k > 0).then(|| (cs / k as f64, bs / k as f64))
        })
    }
}
