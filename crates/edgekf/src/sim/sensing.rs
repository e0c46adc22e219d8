//! The sensing stage: the mean of the T measurements of every directed edge,
//! `ȳ = x + chol(R_ij / T) η`, drawn directly — with `H = 1_T ⊗ I_D` every estimator depends on
//! the T samples only through their mean, which is exactly `N(z_ij, R_ij / T)` (DESIGN.md), so
//! this is not an approximation. One noise realisation per T value per step, shared by all the
//! estimators that use that T (common random numbers).

use crate::linalg::{batch_gemv, psd_factor, to_row_major, with_avx2};
use crate::step::Reads;
use nalgebra::DMatrix;

/// Measurement-mean noise for each distinct T.
#[derive(Debug, Clone)]
pub(crate) struct Sensing {
    /// The distinct T values, ascending.
    pub(crate) t_values: Vec<usize>,
    /// Per T: `chol(R_e / T)` row-major per edge (M × D × D).
    factors: Vec<Vec<f64>>,
    /// Per T: the noise `v̄` (M·D rows × runs).
    pub(crate) vbar: Vec<Vec<f64>>,
    d: usize,
    runs: usize,
}

impl Sensing {
    pub(crate) fn new(
        meas_cov: &[DMatrix<f64>],
        d: usize,
        t_values: Vec<usize>,
        runs: usize,
    ) -> Self {
        let m = meas_cov.len();
        let factors = t_values
            .iter()
            .map(|&t| {
                let mut out = vec![0.0; m * d * d];
                for (e, r) in meas_cov.iter().enumerate() {
                    let f = psd_factor(&(r / t as f64)).expect("checked PSD");
                    to_row_major(&f, &mut out[e * d * d..(e + 1) * d * d]);
                }
                out
            })
            .collect();
        let vbar = vec![vec![0.0; m * d * runs]; t_values.len()];
        Self {
            t_values,
            factors,
            vbar,
            d,
            runs,
        }
    }

    /// The index of T in [`Sensing::t_values`].
    pub(crate) fn index_of(&self, t: usize) -> usize {
        self.t_values.binary_search(&t).expect("listed")
    }

    /// The measurement-mean noise of T value `index` for [`EdgeStates::form`]: the stored `v̄`
    /// (zero while `active` is false: R = 0, no η drawn), or with D = 2 the factors and this
    /// step's normals `eta`, applied in `form` (the same products in the same order, so the same
    /// bits, without a pass that writes `v̄` and one that reads it back).
    pub(crate) fn noise<'a>(&'a self, index: usize, eta: &'a [f64], active: bool) -> MeasNoise<'a> {
        if active && self.d == 2 {
            MeasNoise::Factor {
                factor: &self.factors[index],
                eta,
            }
        } else {
            MeasNoise::Mean(&self.vbar[index])
        }
    }

    /// `v̄ = chol(R/T) η` for every T from this step's normals. With D = 2 nothing is stored:
    /// [`EdgeStates::form`] applies the factor as it forms `ȳ` ([`Sensing::noise`]).
    pub(crate) fn update(&mut self, eta: &[f64]) {
        let (d, runs) = (self.d, self.runs);
        if d == 2 {
            return;
        }
        for (f, v) in self.factors.iter().zip(self.vbar.iter_mut()) {
            let m = f.len() / (d * d);
            for e in 0..m {
                let span = e * d * runs..(e + 1) * d * runs;
                batch_gemv(
                    &f[e * d * d..(e + 1) * d * d],
                    d,
                    d,
                    &eta[span.clone()],
                    &mut v[span],
                    runs,
                );
            }
        }
    }
}

/// The noise `v̄` of the measurement means, as [`EdgeStates::form`] takes it.
#[derive(Debug, Clone, Copy)]
pub(crate) enum MeasNoise<'a> {
    /// `v̄` itself (M·D rows × runs).
    Mean(&'a [f64]),
    /// D = 2: `v̄_e = chol(R_e / T) η_e`, each edge's factor row-major (M × 4) and the normals
    /// `η` (M·2 rows × runs).
    Factor {
        /// The factors.
        factor: &'a [f64],
        /// This step's normals.
        eta: &'a [f64],
    },
}

/// What agent `i` senses of each directed edge `(i, j)` at step k, from the positions and the
/// inputs of the previous step: the true edge `x = z_i − z_j` (for the metrics only), the
/// measurement mean `ȳ = x + v̄`, and the prediction increment `Δt (u^i_{k−1} − u^j_{k−1})`
/// (thesis 4.29; what the agent can form when the neighbour's input arrives). All arrays have
/// runs innermost: positions and inputs N·D rows, the edge arrays M·D rows.
pub(crate) struct EdgeStates<'a> {
    /// True edges `x_k`.
    pub(crate) x: &'a mut [f64],
    /// Measurement means `ȳ_k`.
    pub(crate) y: &'a mut [f64],
    /// Prediction increments.
    pub(crate) du: &'a mut [f64],
}

impl EdgeStates<'_> {
    /// Forms the edge arrays of `edges` from positions `z`, inputs `u` and the measurement
    /// noise: `ȳ` always, `x` and `Δu` where `want` asks for them (compiled for AVX2 when the
    /// CPU has it, without fused multiply–add: the bits of the portable code; `ȳ` is
    /// `(z_i − z_j) + v̄` whether `x` is stored or not, the same bits).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn form(
        &mut self,
        edges: &[(usize, usize)],
        z: &[f64],
        u: &[f64],
        noise: MeasNoise<'_>,
        want: Reads,
        d: usize,
        dt: f64,
        runs: usize,
    ) {
        let inputs = Inputs { z, u, dt, runs };
        if d == 2 {
            with_avx2(
                #[inline(always)]
                || self.form2(edges, &inputs, noise, want),
            );
            return;
        }
        let MeasNoise::Mean(vbar) = noise else {
            unreachable!("the factor form is D = 2 only")
        };
        for (e, &(i, j)) in edges.iter().enumerate() {
            for a in 0..d {
                let (re, ri, rj) = ((e * d + a) * runs, (i * d + a) * runs, (j * d + a) * runs);
                let (zi, zj) = (&z[ri..ri + runs], &z[rj..rj + runs]);
                let v = &vbar[re..re + runs];
                for ((y, v), (zia, zja)) in self.y[re..re + runs]
                    .iter_mut()
                    .zip(v)
                    .zip(zi.iter().zip(zj))
                {
                    *y = (zia - zja) + v;
                }
                if want.truth {
                    for (x, (zia, zja)) in self.x[re..re + runs].iter_mut().zip(zi.iter().zip(zj)) {
                        *x = zia - zja;
                    }
                }
                if want.increments {
                    let (ui, uj) = (&u[ri..ri + runs], &u[rj..rj + runs]);
                    for (dv, (uia, uja)) in self.du[re..re + runs].iter_mut().zip(ui.iter().zip(uj))
                    {
                        *dv = dt * (uia - uja);
                    }
                }
            }
        }
    }

    /// D = 2: both coordinates of an edge, a pass over the runs for each array formed.
    #[inline(always)]
    fn form2(
        &mut self,
        edges: &[(usize, usize)],
        inp: &Inputs<'_>,
        noise: MeasNoise<'_>,
        want: Reads,
    ) {
        let Inputs { z, u, dt, runs } = *inp;
        for (e, &(i, j)) in edges.iter().enumerate() {
            let (re, ri, rj) = (e * 2 * runs, i * 2 * runs, j * 2 * runs);
            let (zi, zj) = (&z[ri..ri + 2 * runs], &z[rj..rj + 2 * runs]);
            let (y0, y1) = self.y[re..re + 2 * runs].split_at_mut(runs);
            match noise {
                MeasNoise::Mean(vbar) => {
                    let v = &vbar[re..re + 2 * runs];
                    for r in 0..runs {
                        y0[r] = (zi[r] - zj[r]) + v[r];
                        y1[r] = (zi[runs + r] - zj[runs + r]) + v[runs + r];
                    }
                }
                MeasNoise::Factor { factor, eta } => {
                    let c = &factor[e * 4..e * 4 + 4];
                    let (h0, h1) = eta[re..re + 2 * runs].split_at(runs);
                    for r in 0..runs {
                        // `v̄ = chol(R/T) η` as `Sensing::update` evaluates it for D ≠ 2.
                        y0[r] = (zi[r] - zj[r]) + (c[0] * h0[r] + c[1] * h1[r]);
                        y1[r] = (zi[runs + r] - zj[runs + r]) + (c[2] * h0[r] + c[3] * h1[r]);
                    }
                }
            }
            if want.truth {
                let (x0, x1) = self.x[re..re + 2 * runs].split_at_mut(runs);
                for r in 0..runs {
                    x0[r] = zi[r] - zj[r];
                    x1[r] = zi[runs + r] - zj[runs + r];
                }
            }
            if want.increments {
                let (ui, uj) = (&u[ri..ri + 2 * runs], &u[rj..rj + 2 * runs]);
                let (d0, d1) = self.du[re..re + 2 * runs].split_at_mut(runs);
                for r in 0..runs {
                    d0[r] = dt * (ui[r] - uj[r]);
                    d1[r] = dt * (ui[runs + r] - uj[runs + r]);
                }
            }
        }
    }
}

/// The per-agent inputs of [`EdgeStates::form`].
#[derive(Clone, Copy)]
struct Inputs<'a> {
    z: &'a [f64],
    u: &'a [f64],
    dt: f64,
    runs: usize,
}
