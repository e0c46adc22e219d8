//! The sensing stage: the mean of the T measurements of every directed edge,
//! `ȳ = x + chol(R_ij / T) η`, drawn directly — with `H = 1_T ⊗ I_D` every estimator depends on
//! the T samples only through their mean, which is exactly `N(z_ij, R_ij / T)` (DESIGN.md), so
//! this is not an approximation. One noise realisation per T value per step, shared by all the
//! estimators that use that T (common random numbers).

use crate::linalg::{batch_gemv, psd_factor, to_row_major, with_avx2};
use crate::step::{form_edge_means, Reads};
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
pub(crate) use crate::step::MeasNoise;

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
    /// noise, each where `want` asks for it (compiled for AVX2 when the CPU has it, without
    /// fused multiply–add: the bits of the portable code; `ȳ` is `(z_i − z_j) + v̄` by
    /// [`form_edge_means`], whether `x` is stored or not and whoever forms it).
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
        let inputs = Inputs { z, u, d, dt, runs };
        if d == 2 {
            with_avx2(
                #[inline(always)]
                || self.form_edges::<2>(edges, &inputs, noise, want),
            );
        } else {
            self.form_edges::<0>(edges, &inputs, noise, want);
        }
    }

    /// Every edge's arrays, a pass over the runs for each; `D2` is 2 for D = 2 (the loops then
    /// know their length), else 0 (D from `inp`).
    #[inline(always)]
    fn form_edges<const D2: usize>(
        &mut self,
        edges: &[(usize, usize)],
        inp: &Inputs<'_>,
        noise: MeasNoise<'_>,
        want: Reads,
    ) {
        let Inputs { z, u, d, dt, runs } = *inp;
        let d = if D2 == 0 { d } else { D2 };
        let block = d * runs;
        for (e, &(i, j)) in edges.iter().enumerate() {
            let (re, ri, rj) = (e * block, i * block, j * block);
            if want.means {
                form_edge_means(e, (i, j), z, noise, (d, runs), &mut self.y[re..re + block]);
            }
            if want.truth {
                let (zi, zj) = (&z[ri..ri + block], &z[rj..rj + block]);
                for (x, (zia, zja)) in self.x[re..re + block].iter_mut().zip(zi.iter().zip(zj)) {
                    *x = zia - zja;
                }
            }
            if want.increments {
                let (ui, uj) = (&u[ri..ri + block], &u[rj..rj + block]);
                for (dv, (uia, uja)) in self.du[re..re + block].iter_mut().zip(ui.iter().zip(uj)) {
                    *dv = dt * (uia - uja);
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
    d: usize,
    dt: f64,
    runs: usize,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::step::Means;

    /// `Step::means` forms the sensing stage's `ȳ` bit for bit, edge by edge or whole, from the
    /// positions and either noise form, and reads a formed array back at the right rows.
    #[test]
    fn means_formed_on_request_have_the_bits_of_the_array() {
        let edges = [(0, 1), (1, 0), (1, 2), (2, 0)];
        let (n, m) = (3, edges.len());
        // Non-trivial values (an LCG), so that a wrong order of operations changes bits.
        let mut s = 0x9e37_79b9_u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 7.0 - 3.0
        };
        for (d, runs) in [(2, 21), (3, 5)] {
            let z: Vec<f64> = (0..n * d * runs).map(|_| next()).collect();
            let u: Vec<f64> = (0..n * d * runs).map(|_| next()).collect();
            let eta: Vec<f64> = (0..m * d * runs).map(|_| next()).collect();
            let factor: Vec<f64> = (0..m * d * d).map(|_| next()).collect();
            let noises = if d == 2 {
                vec![
                    MeasNoise::Factor {
                        factor: &factor,
                        eta: &eta,
                    },
                    MeasNoise::Mean(&eta),
                ]
            } else {
                vec![MeasNoise::Mean(&eta)]
            };
            for noise in noises {
                let (mut x, mut y, mut du) = (
                    vec![0.0; m * d * runs],
                    vec![0.0; m * d * runs],
                    vec![0.0; m * d * runs],
                );
                EdgeStates {
                    x: &mut x,
                    y: &mut y,
                    du: &mut du,
                }
                .form(&edges, &z, &u, noise, Reads::ALL, d, 0.1, runs);
                let raw = Means::raw(&edges, &z, noise, d, runs);
                let mut all = vec![f64::NAN; y.len()];
                raw.all_into(&mut all);
                let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&all), bits(&y), "D = {d}");
                let block = d * runs;
                let mut two = vec![f64::NAN; 2 * block];
                raw.edges_into(1, &mut two);
                assert_eq!(bits(&two), bits(&y[block..3 * block]), "D = {d}");
                Means::formed(&y, d, runs).edges_into(2, &mut two);
                assert_eq!(bits(&two), bits(&y[2 * block..4 * block]), "D = {d}");
            }
        }
    }
}
