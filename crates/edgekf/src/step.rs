//! What one step's stages hand to the estimators and the controllers: the faults of the step
//! ([`Faults`]), the target formation ([`Target`]) and everything an estimator may read
//! ([`Step`]). These types sit below both [`crate::estimate`] and [`crate::control`], so that
//! neither imports the other.

/// Which measurements and messages reached whom at this step: the faults stage's output, shared
/// by every estimator of a run (so different estimators see the same faults: paired
/// comparisons). All arrays have runs innermost.
#[derive(Debug, Clone)]
pub struct Faults {
    runs: usize,
    agents: usize,
    edges: Vec<(usize, usize)>,
    measurement_faults: bool,
    observed: Vec<bool>,
    comm: Vec<f64>,
    present: Vec<bool>,
    /// Whether a neighbour's message can be lost by itself (an agent on a real network); then
    /// `hears` holds, per edge and run, whether it was heard (and observed).
    messages_lost: bool,
    hears: Vec<bool>,
}

impl Faults {
    /// No faults: every measurement and message arrives, every agent is present.
    pub fn none(agents: usize, edges: &[(usize, usize)], runs: usize) -> Self {
        Self {
            runs,
            agents,
            edges: edges.to_vec(),
            measurement_faults: false,
            observed: vec![true; edges.len() * runs],
            comm: Vec::new(),
            present: vec![true; agents * runs],
            messages_lost: false,
            hears: Vec::new(),
        }
    }

    /// Runs in the batch.
    pub fn runs(&self) -> usize {
        self.runs
    }

    /// Whether any measurement can be missing in this scenario (lost or unavailable edges,
    /// departed agents). When `false`, [`Faults::observed`] is always `true`, and filters may
    /// share one gain across runs.
    pub fn measurement_faults(&self) -> bool {
        self.measurement_faults
    }

    /// Whether agent `i` received its measurement of edge `e = (i, j)` in run `r` this step
    /// (Li & Rajan's `β_ij,k`: the edge is available, not permanently lost, and both agents are
    /// present).
    #[inline]
    pub fn observed(&self, e: usize, r: usize) -> bool {
        self.observed[e * self.runs + r]
    }

    /// [`Faults::observed`] for every run of edge `e`.
    #[inline]
    pub fn observed_row(&self, e: usize) -> &[bool] {
        &self.observed[e * self.runs..(e + 1) * self.runs]
    }

    /// Whether agent `i` heard neighbour `j` over edge `e = (i, j)` in run `r` this step: the
    /// message the estimator needs from `j` (its input, or GA-RKF's consensus terms) arrived.
    /// In the simulator one availability draw removes the measurement and the message together,
    /// so this is [`Faults::observed`]; an agent on a real network can lose the message alone
    /// ([`crate::agent`]).
    #[inline]
    pub fn hears(&self, e: usize, r: usize) -> bool {
        self.hears_row(e)[r]
    }

    /// [`Faults::hears`] for every run of edge `e`.
    #[inline]
    pub fn hears_row(&self, e: usize) -> &[bool] {
        if self.messages_lost {
            &self.hears[e * self.runs..(e + 1) * self.runs]
        } else {
            self.observed_row(e)
        }
    }

    /// Whether neighbour `j`'s input `u^j_{k−1}` reached agent `i` over edge `e = (i, j)` in run
    /// `r`, for an estimator whose links lose the message with probability `p_fail` per step
    /// (thesis §6.1). One availability draw removes the measurement and the message together
    /// (Li & Rajan have no separate communication model); the chapter 6 failures come from one
    /// uniform per directed edge, step and run shared by all estimators, so different
    /// `p_fail` are paired.
    #[inline]
    pub fn input_arrives(&self, e: usize, r: usize, p_fail: f64) -> bool {
        if !self.hears(e, r) || p_fail >= 1.0 {
            return false;
        }
        p_fail <= 0.0 || self.comm[e * self.runs + r] >= p_fail
    }

    /// `!`[`Faults::input_arrives`] for every run of edge `e`, written to `lost`: the runs in
    /// which agent i must predict neighbour j's input this step. Branch-free over the runs.
    ///
    /// # Panics
    /// When `lost` is not one entry per run.
    #[inline(always)]
    pub fn inputs_lost(&self, e: usize, p_fail: f64, lost: &mut [bool]) {
        let observed = self.hears_row(e);
        assert_eq!(lost.len(), observed.len(), "one entry per run");
        if p_fail >= 1.0 {
            lost.fill(true);
        } else if p_fail <= 0.0 {
            for (l, &o) in lost.iter_mut().zip(observed) {
                *l = !o;
            }
        } else {
            let comm = &self.comm[e * self.runs..(e + 1) * self.runs];
            for ((l, &o), &c) in lost.iter_mut().zip(observed).zip(comm) {
                *l = !(o & (c >= p_fail));
            }
        }
    }

    /// The chapter 6 link-failure uniforms of edges `first..first + count` in run 0 (empty when
    /// none are drawn).
    pub(crate) fn comm_row(&self, first: usize, count: usize) -> Vec<f64> {
        if self.comm.is_empty() {
            return Vec::new();
        }
        (first..first + count)
            .map(|e| self.comm[e * self.runs])
            .collect()
    }

    /// Whether agent `i` is present (has not departed) in run `r`.
    #[inline]
    pub fn present(&self, i: usize, r: usize) -> bool {
        self.present[i * self.runs + r]
    }

    /// Per run, whether agent `i` is present.
    #[inline]
    pub fn present_row(&self, i: usize) -> &[bool] {
        &self.present[i * self.runs..(i + 1) * self.runs]
    }

    /// Per run, whether edge `e` is tracked ([`Self::tracked`]).
    #[inline]
    pub fn tracked_row(&self, e: usize) -> &[bool] {
        self.present_row(self.edges[e].0)
    }

    /// Whether edge `e` is tracked in run `r`: its measuring agent is present.
    #[inline]
    pub fn tracked(&self, e: usize, r: usize) -> bool {
        self.present(self.edges[e].0, r)
    }

    /// Number of agents.
    pub fn agents(&self) -> usize {
        self.agents
    }

    /// Mutable access for the faults stage and the agents (crate-internal).
    pub(crate) fn parts_mut(&mut self) -> FaultsMut<'_> {
        FaultsMut {
            measurement_faults: &mut self.measurement_faults,
            observed: &mut self.observed,
            comm: &mut self.comm,
            present: &mut self.present,
            messages_lost: &mut self.messages_lost,
            hears: &mut self.hears,
        }
    }
}

/// Write access to [`Faults`].
pub(crate) struct FaultsMut<'a> {
    pub(crate) measurement_faults: &'a mut bool,
    pub(crate) observed: &'a mut Vec<bool>,
    pub(crate) comm: &'a mut Vec<f64>,
    pub(crate) present: &'a mut Vec<bool>,
    pub(crate) messages_lost: &'a mut bool,
    pub(crate) hears: &'a mut Vec<bool>,
}

/// The target formation at this step (Li & Rajan eq. 2: `Z* = Θ* P + t* 1ᵀ`), when the scenario
/// has a maneuver.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// `Θ*`, D × D row-major.
    pub theta: Vec<f64>,
    /// `t*` (D).
    pub shift: Vec<f64>,
    /// `Z*`, agent-major (`i * D + d`).
    pub positions: Vec<f64>,
    /// `Ż*`, agent-major.
    pub velocities: Vec<f64>,
}

/// Which of a [`Step`]'s derived fields an estimator reads ([`crate::estimate::Estimator::reads`]),
/// so that the simulation forms only those: every step's `u_prev`, `faults`, `target` and
/// [`Step::means`] are always there; `y` unless the estimator forms the means itself, `du` and
/// `truth` only when read (and `truth` at a report, for the metrics). A field not read holds
/// stale values or NaN.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reads {
    /// [`Step::du`], the prediction increments.
    pub increments: bool,
    /// [`Step::truth`], the true edges.
    pub truth: bool,
    /// [`Step::y`], the measurement means as an array. Without it the estimator forms the rows
    /// it reads with [`Step::means`] (the same bits), which saves the pass that writes the
    /// array and the one that reads it back.
    pub means: bool,
}

impl Reads {
    /// Every field (the default: an estimator that does not say reads everything).
    pub const ALL: Reads = Reads {
        increments: true,
        truth: true,
        means: true,
    };
    /// The measurement means and the inputs only.
    pub const MEANS: Reads = Reads {
        increments: false,
        truth: false,
        means: true,
    };
    /// The means, the inputs and the prediction increments.
    pub const INCREMENTS: Reads = Reads {
        increments: true,
        truth: false,
        means: true,
    };

    /// The same, with the means formed by the estimator ([`Step::means`]) instead of read
    /// from [`Step::y`].
    pub const fn forming_means(self) -> Reads {
        Reads {
            means: false,
            ..self
        }
    }
}

/// The noise of the measurement means `v̄`, as the sensing stage has it.
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

/// The measurement means `ȳ_k` of a step (MD rows × runs), for an estimator that forms the rows
/// it reads ([`Reads::means`] false): either the formed array, or what it is formed from — the
/// positions and the noise — with the one expression of the sensing stage
/// (`step::form_edge_means`), so the rows have the bits of the array.
#[derive(Debug, Clone, Copy)]
pub struct Means<'a>(MeansOf<'a>);

#[derive(Debug, Clone, Copy)]
enum MeansOf<'a> {
    /// The array and the length of an edge's rows (D × runs).
    Formed(&'a [f64], usize),
    Raw {
        edges: &'a [(usize, usize)],
        z: &'a [f64],
        noise: MeasNoise<'a>,
        d: usize,
        runs: usize,
    },
}

impl<'a> Means<'a> {
    /// The means of an array already formed (`d` rows per edge, runs innermost).
    pub fn formed(y: &'a [f64], d: usize, runs: usize) -> Self {
        Self(MeansOf::Formed(y, d * runs))
    }

    /// The means of `edges` from the positions `z` (N·D rows × runs) and the noise.
    pub(crate) fn raw(
        edges: &'a [(usize, usize)],
        z: &'a [f64],
        noise: MeasNoise<'a>,
        d: usize,
        runs: usize,
    ) -> Self {
        Self(MeansOf::Raw {
            edges,
            z,
            noise,
            d,
            runs,
        })
    }

    /// Edges `first..first + k`'s rows (`k`·D rows × runs, the length of `out`) into `out`.
    #[inline]
    pub fn edges_into(&self, first: usize, out: &mut [f64]) {
        match self.0 {
            MeansOf::Formed(y, block) => {
                let start = first * block;
                out.copy_from_slice(&y[start..start + out.len()]);
            }
            MeansOf::Raw {
                edges,
                z,
                noise,
                d,
                runs,
            } => {
                let block = d * runs;
                crate::linalg::with_avx2(
                    #[inline(always)]
                    || {
                        for (k, rows) in out.chunks_exact_mut(block).enumerate() {
                            let e = first + k;
                            form_edge_means(e, edges[e], z, noise, (d, runs), rows);
                        }
                    },
                );
            }
        }
    }

    /// Every edge's rows (MD rows × runs) into `out`.
    pub fn all_into(&self, out: &mut [f64]) {
        self.edges_into(0, out);
    }
}

/// Edge `e = (i, j)`'s measurement means (D rows × runs) into `y`: `(z_i − z_j) + v̄_e` — the
/// one expression by which the sensing stage and [`Means`] form them (so both have the same
/// bits). With D = 2 and the factor form, `v̄_e = chol(R_e / T) η_e` is applied here.
#[inline(always)]
pub(crate) fn form_edge_means(
    e: usize,
    (i, j): (usize, usize),
    z: &[f64],
    noise: MeasNoise<'_>,
    (d, runs): (usize, usize),
    y: &mut [f64],
) {
    let (re, ri, rj) = (e * d * runs, i * d * runs, j * d * runs);
    let (zi, zj) = (&z[ri..ri + d * runs], &z[rj..rj + d * runs]);
    match noise {
        MeasNoise::Factor { factor, eta } if d == 2 => {
            let c: &[f64; 4] = factor[e * 4..e * 4 + 4].try_into().expect("a 2 × 2 factor");
            let eta = &eta[re..re + 2 * runs];
            let y = &mut y[..2 * runs];
            let from = crate::linalg::avx2_prefix!(means2_avx2(c, (zi, zj), eta, y, runs));
            means2_runs(c, (zi, zj), eta, y, from..runs);
        }
        MeasNoise::Factor { .. } => unreachable!("the factor form is D = 2 only"),
        MeasNoise::Mean(vbar) => {
            let v = &vbar[re..re + d * runs];
            for (((y, v), zia), zja) in y[..d * runs].iter_mut().zip(v).zip(zi).zip(zj) {
                *y = (zia - zja) + v;
            }
        }
    }
}

/// Runs `span` of one edge's two rows of means with D = 2: `ȳ = (z_i − z_j) + chol(R/T) η`,
/// `v̄` evaluated as `Sensing::update` does for D ≠ 2 (`c₀ η₀ + c₁ η₁`). `zi`, `zj` and `y`
/// hold two rows of `runs`, `eta` the edge's two rows of normals.
#[inline(always)]
fn means2_runs(
    c: &[f64; 4],
    (zi, zj): (&[f64], &[f64]),
    eta: &[f64],
    y: &mut [f64],
    span: std::ops::Range<usize>,
) {
    let runs = y.len() / 2;
    let (h0, h1) = eta.split_at(runs);
    let (y0, y1) = y.split_at_mut(runs);
    for r in span {
        y0[r] = (zi[r] - zj[r]) + (c[0] * h0[r] + c[1] * h1[r]);
        y1[r] = (zi[runs + r] - zj[runs + r]) + (c[2] * h0[r] + c[3] * h1[r]);
    }
}

/// [`means2_runs`] four runs at a time in AVX2 registers, up to the last multiple of four
/// (returned): the same operations in the same order, so the same bits (no fused
/// multiply–add), without the loop set-up the compiler generates per edge (tests of whether the
/// rows overlap, a scalar loop for the last runs).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn means2_avx2(
    c: &[f64; 4],
    (zi, zj): (&[f64], &[f64]),
    eta: &[f64],
    y: &mut [f64],
    runs: usize,
) -> usize {
    use std::arch::x86_64::*;
    assert!(zi.len() >= 2 * runs && zj.len() >= 2 * runs);
    assert!(eta.len() == 2 * runs && y.len() == 2 * runs);
    let [c0, c1, c2, c3] = c.map(|v| _mm256_set1_pd(v));
    let (pi, pj, h, out) = (zi.as_ptr(), zj.as_ptr(), eta.as_ptr(), y.as_mut_ptr());
    let full = runs - runs % 4;
    let mut r = 0;
    while r < full {
        // SAFETY: r + 4 ≤ runs, so every load and store below is within the rows asserted
        // above (two rows of `runs` each).
        unsafe {
            let ld = |p: *const f64| _mm256_loadu_pd(p);
            let (g0, g1) = (ld(h.add(r)), ld(h.add(runs + r)));
            let d0 = _mm256_sub_pd(ld(pi.add(r)), ld(pj.add(r)));
            let d1 = _mm256_sub_pd(ld(pi.add(runs + r)), ld(pj.add(runs + r)));
            let v0 = _mm256_add_pd(_mm256_mul_pd(c0, g0), _mm256_mul_pd(c1, g1));
            let v1 = _mm256_add_pd(_mm256_mul_pd(c2, g0), _mm256_mul_pd(c3, g1));
            _mm256_storeu_pd(out.add(r), _mm256_add_pd(d0, v0));
            _mm256_storeu_pd(out.add(runs + r), _mm256_add_pd(d1, v1));
        }
        r += 4;
    }
    full
}

/// Everything an estimator may read at step `k`: the outputs of the stages that run before
/// estimation (world → faults → sensing). Batches have runs innermost.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    /// Step index k (1-based).
    pub k: usize,
    /// Δt.
    pub dt: f64,
    /// Measurement means `ȳ_k` for this estimator's T (MD rows); meaningful where observed.
    /// Formed unless the estimator forms them itself ([`Reads::means`]).
    pub y: &'a [f64],
    /// The same means, for an estimator that forms the rows it reads ([`Reads::means`] false).
    pub means: Means<'a>,
    /// Node inputs of the previous step `u_{k−1}` (ND rows).
    pub u_prev: &'a [f64],
    /// Prediction increments `Δt (u^i_{k−1} − u^j_{k−1})` per directed edge (MD rows): what the
    /// agent knows when the neighbour's input arrives.
    pub du: &'a [f64],
    /// Measurement and message availability, agents present.
    pub faults: &'a Faults,
    /// The true edge states `x_k` (MD rows). Only the `oracle` reads them; formed for an
    /// estimator whose [`Reads::truth`] is set, and at a report for the metrics.
    pub truth: &'a [f64],
    /// The target formation at step k, if the scenario has one.
    pub target: Option<&'a Target>,
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Values whose rounding shows a changed order of operations, with zeros of both signs.
    pub(crate) fn mixed(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed | 1;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                match s % 9 {
                    0 => 0.0,
                    1 => -0.0,
                    _ => (s >> 11) as f64 / (1u64 << 53) as f64 * 6.0 - 3.0,
                }
            })
            .collect()
    }

    /// The bit patterns of `v`, to compare values bit for bit (`−0` against `+0` included).
    pub(crate) fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|f| f.to_bits()).collect()
    }

    /// The AVX2 means (four runs at a time, then the last ones) have the bits of the loop over
    /// the runs, for every count of runs from 1 to 19 (each tail, several full vectors).
    #[test]
    fn the_vector_means_have_the_bits_of_the_loop() {
        for runs in 1..20 {
            let (zi, zj, eta) = (mixed(2 * runs, 1), mixed(2 * runs, 2), mixed(2 * runs, 3));
            for c in [[0.3, 0.0, -0.7, 1.9], [1.1, 0.2, 0.2, 1.1]] {
                // The loop `form_edge_means` ran before it had a vector path.
                let (h0, h1) = eta.split_at(runs);
                let mut want = vec![f64::NAN; 2 * runs];
                let (y0, y1) = want.split_at_mut(runs);
                for r in 0..runs {
                    y0[r] = (zi[r] - zj[r]) + (c[0] * h0[r] + c[1] * h1[r]);
                    y1[r] = (zi[runs + r] - zj[runs + r]) + (c[2] * h0[r] + c[3] * h1[r]);
                }
                let mut got = vec![f64::NAN; 2 * runs];
                let factor = MeasNoise::Factor {
                    factor: &c,
                    eta: &eta,
                };
                let z = [zi.clone(), zj.clone()].concat();
                form_edge_means(0, (0, 1), &z, factor, (2, runs), &mut got);
                assert_eq!(bits(&got), bits(&want), "{runs} runs, factor {c:?}");
            }
        }
    }
}
