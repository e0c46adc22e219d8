//! Named metrics, collected at the reported steps by observers (in the style of argmin's): each
//! metric measures one value per run from what the step's stages produced; the engine stores
//! them under their names and knows nothing else about them. A new output is a new [`Metric`]
//! listed in [`metrics_for`], not a change of the engine.
//!
//! Names and meanings are fixed by the output contract (DESIGN.md):
//! `est_error` ε_k = ‖x_k − x̂_{k|k}‖ over the tracked directed edges (thesis 4.34),
//! `est_error_sq` ε_k², `cov_trace` (the estimator's summed posterior trace of the tracked
//! edges), `procrustes` (thesis Def. 2.9, over the agents present), `tracking_error`
//! δ_k = ‖Z_k − Z_k*‖²_F / N over the agents present (Li & Rajan eq. 4), `edge_cov_trace`, and the
//! quantities an estimator reports itself (e.g. GA-RKF's `psi`).

use crate::by_dim;
use crate::estimate::{Estimator, Step};
use crate::framework::Framework;
use crate::metrics::procrustes_where;
use crate::scenario::{EstimatorDef, Scenario};

/// What a metric reads at a reported step.
#[derive(Clone, Copy)]
pub struct Measure<'a> {
    /// The step's stage outputs (faults, truth, target).
    pub step: &'a Step<'a>,
    /// The estimator, after its update.
    pub estimator: &'a dyn Estimator,
    /// Positions `z_k` (ND rows × runs).
    pub z: &'a [f64],
    /// The framework.
    pub framework: &'a Framework,
    /// Runs in the batch.
    pub runs: usize,
}

/// A named per-run measurement.
pub trait Metric: Send + Sync {
    /// The name in `metrics.csv`.
    fn name(&self) -> &str;
    /// One value per run into `out`.
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]);
    /// Whether a NaN value means "undefined in this run at this step" (e.g. GA-RKF's ψ before
    /// any agent has one) rather than a divergence. Statistics then use the runs where it is
    /// defined; an infinite value still stops the estimator.
    fn partial(&self) -> bool {
        false
    }
    /// The metric's unit as a power of length (`est_error`: m → 1; `cov_trace`: m² → 2), for
    /// the divergence bound (the module `sim::divergence`); `None` for a metric without one.
    fn length_power(&self) -> Option<i32> {
        None
    }
}

/// `ε_k²` over the tracked edges.
struct EstErrorSq {
    root: bool,
}

impl Metric for EstErrorSq {
    fn name(&self) -> &str {
        if self.root {
            "est_error"
        } else {
            "est_error_sq"
        }
    }
    fn length_power(&self) -> Option<i32> {
        Some(if self.root { 1 } else { 2 })
    }
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]) {
        let runs = m.runs;
        let d = m.framework.dim();
        let xh = m.estimator.estimates();
        let x = m.step.truth;
        let faults = m.step.faults;
        let me = m.framework.graph().num_edges();
        // Each run's sum over the edges in order, the runs innermost (contiguous rows); an
        // untracked edge adds +0, which leaves a sum of squares as it is.
        out.fill(0.0);
        for e in 0..me {
            let tracked = faults.measurement_faults().then(|| faults.tracked_row(e));
            for a in e * d..(e + 1) * d {
                let (xa, ha) = (&x[a * runs..(a + 1) * runs], &xh[a * runs..(a + 1) * runs]);
                match tracked {
                    Some(t) => {
                        for (((o, &xr), &hr), &keep) in out.iter_mut().zip(xa).zip(ha).zip(t) {
                            let v = xr - hr;
                            *o += if keep { v * v } else { 0.0 };
                        }
                    }
                    None => {
                        for ((o, &xr), &hr) in out.iter_mut().zip(xa).zip(ha) {
                            let v = xr - hr;
                            *o += v * v;
                        }
                    }
                }
            }
        }
        if self.root {
            for o in out.iter_mut() {
                *o = o.sqrt();
            }
        }
    }
}

/// The estimator's `cov_trace`.
struct CovTrace;

impl Metric for CovTrace {
    fn name(&self) -> &str {
        "cov_trace"
    }
    fn length_power(&self) -> Option<i32> {
        Some(2)
    }
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]) {
        m.estimator.cov_trace(m.step, out);
    }
}

/// Procrustes error of the present agents' positions.
struct Procrustes;

impl Metric for Procrustes {
    fn name(&self) -> &str {
        "procrustes"
    }
    fn length_power(&self) -> Option<i32> {
        Some(1)
    }
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]) {
        let runs = m.runs;
        let n = m.framework.agents();
        let f = m.step.faults;
        let cfg = m.framework.config();
        by_dim!(m.framework.dim(), D => {
            for (r, o) in out.iter_mut().enumerate() {
                *o = procrustes_where::<D>(
                    n,
                    |i| f.present(i, r),
                    |i, d| m.z[(i * D + d) * runs + r],
                    cfg,
                );
            }
        });
    }
}

/// δ_k = Σ_{present i} ‖z_i − z_i*‖² / (number present).
struct TrackingError;

impl Metric for TrackingError {
    fn name(&self) -> &str {
        "tracking_error"
    }
    fn length_power(&self) -> Option<i32> {
        Some(2)
    }
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]) {
        let Some(t) = m.step.target else {
            out.fill(f64::NAN);
            return;
        };
        let runs = m.runs;
        let d = m.framework.dim();
        let n = m.framework.agents();
        for (r, o) in out.iter_mut().enumerate() {
            let mut s = 0.0;
            let mut count = 0usize;
            for i in (0..n).filter(|&i| m.step.faults.present(i, r)) {
                count += 1;
                for a in 0..d {
                    let v = m.z[(i * d + a) * runs + r] - t.positions[i * d + a];
                    s += v * v;
                }
            }
            *o = s / count.max(1) as f64;
        }
    }
}

/// A quantity the estimator reports itself.
struct Quantity(&'static str);

impl Metric for Quantity {
    fn name(&self) -> &str {
        self.0
    }
    fn measure(&self, m: &Measure<'_>, out: &mut [f64]) {
        if !m.estimator.quantity(self.0, m.step, out) {
            out.fill(f64::NAN);
        }
    }
    fn partial(&self) -> bool {
        true
    }
}

/// The metric called `name`: a built-in one, or a quantity the estimator reports itself.
pub fn metric(name: &'static str) -> Box<dyn Metric> {
    match name {
        "est_error" => Box::new(EstErrorSq { root: true }),
        "est_error_sq" => Box::new(EstErrorSq { root: false }),
        "cov_trace" => Box::new(CovTrace),
        "procrustes" => Box::new(Procrustes),
        "tracking_error" => Box::new(TrackingError),
        other => Box::new(Quantity(other)),
    }
}

/// The metrics of estimator `def` in `sc`, in output order ([`Scenario::metrics_of`]).
pub fn metrics_for(sc: &Scenario, def: &EstimatorDef) -> Vec<Box<dyn Metric>> {
    sc.metrics_of(def).into_iter().map(metric).collect()
}
