//! A primal–dual path-following interior-point method for the stress SDPs, with Mehrotra
//! predictor–corrector steps (the default solver).
//!
//! # The problems
//! Every design problem here is a semidefinite program over the equilibrium stresses `w = Z c`
//! (see [`super::StressSpace`]) in the *dual standard form*
//! ```text
//! max bᵀy   s.t.   S_j(y) = C_j − A_j*(y) ⪰ 0 (PSD blocks),   s_r(y) = c_r − a_rᵀ y ≥ 0 (LP rows),
//! ```
//! `y = (c, e)`, with `e` either one scalar (`s` of the conditioning and gap forms) or the ℓ1
//! bounds `p`. Each PSD block is `S = σ L(w) + (γ − η e₀) Π`, where `L(w) = B diag(w) Bᵀ` is
//! the stress matrix and `Π = I − J` the orthogonal projector onto the complement of
//! `span{1, q_1, …, q_D}` (`J` projects onto that span): the blocks act on that complement, where
//! `L(w)` is `Q L Qᵀ` of thesis (3.5). We keep them as `N × N` matrices (rather than
//! `(N − D − 1)`-square ones in a basis `Q`): then every constraint matrix is sparse,
//! `L(w) = Σ_l w_l b_l b_lᵀ` with `b_l = e_i − e_j`, and the Schur complement below is a gather of
//! matrix entries instead of a product with the dense `U = Q B`. Factorisations use `S + J`,
//! which has the same eigenvalues on the complement and eigenvalue 1 on the span.
//!
//! - [`Mode::Condition`] — `max s` s.t. `s Π ⪯ L(w) ⪯ Π`: the best-conditioned stress (thesis
//!   (3.5) with the bound on `λ_max`, see [`super::sdp`]). Always strictly feasible
//!   (`c = 0, s = −1`), bounded (`s ≤ 1`), and `s* > 0` iff a PSD stress of rank `N − D − 1`
//!   exists;
//! - [`Mode::Gap`] — `max s` s.t. `s Π ⪯ L(w)`, `s ≤ λ̄`, `|w_l| ≤ w̄` (thesis (3.5) with
//!   bounded weights);
//! - [`Mode::L1`] — `max −Σ p` s.t. `Π ⪯ L(w) ⪯ κ̄ Π`, `|w_l| ≤ p_l` (the sparse design).
//!
//! # The method
//! The HKM (Helmberg–Kojima–Monteiro) search direction with Mehrotra's predictor–corrector, as
//! in SDPT3 (Toh, Todd, Tütüncü 1999; Todd, Toh, Tütüncü, *SIAM J. Optim.* 8(3), 1998):
//! for the primal `min Σ ⟨C_j, X_j⟩ + cᵀx` s.t. `A(X) = b`, the step solves
//! ```text
//! M Δy = b − σμ A(S⁻¹) + A(ΔX_a ΔS_a S⁻¹),   ΔS = −A*(Δy),
//! ΔX = σμ S⁻¹ − X − sym(X ΔS S⁻¹ + ΔX_a ΔS_a S⁻¹),
//! ```
//! with the Schur complement `M_ik = Σ_j tr(A_{j,i} X_j A_{j,k} S_j⁻¹) + Σ_r a_ri a_rk x_r / s_r`.
//! Because every constraint matrix is a combination of the rank-one `b_l b_lᵀ`, in weight space
//! `M = Zᵀ (Σ_j (Bᵀ X_j B) ∘ (Bᵀ S_j⁻¹ B) + D_LP) Z`: `O(L²)` gathers and one `L × L × m`
//! product, instead of a general solver's `O(m² n'²)`. The predictor (`σ = 0`, no second-order
//! term) gives the affine step `ΔX_a, ΔS_a` and the centring `σ = (μ_a/μ)³`; the corrector reuses
//! the factorised `M`. Primal and dual step lengths are separate, `γ = 0.9 + 0.09 min(α_a)` of the
//! way to the boundary (the boundary from the smallest eigenvalue of `F⁻¹ ΔX F⁻ᵀ`, `F` a Cholesky
//! factor of `X + J`).
//!
//! The dual iterates `y` stay strictly feasible from a strictly feasible start (known in every
//! mode), so **every iterate is a valid design** and `bᵀy` a lower bound; the primal start is
//! feasible too (constructed per mode), and `⟨C, X⟩` is an upper bound once `A(X) = b` holds to
//! round-off. The caller stops on these bounds. The solver stops by itself, returning the last
//! iterate with a [`Status`], when the duality gap stalls (less than halved in 8 iterations, or
//! both step lengths below 1e-9), the Schur complement cannot be factorised, or 150 iterations
//! pass (primal–dual methods take 20–40 here).

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

use super::{dense, Mode, StressSpace};

/// A PSD block `S = σ L(w) + (γ − η e₀) Π`.
#[derive(Debug, Clone, Copy)]
struct Block {
    sigma: f64,
    gamma: f64,
    eta: f64,
}

/// An LP row `s = c − ρ w_l − ε e_k` (`link = (l, ρ)`, `extra = (k, ε)`).
#[derive(Debug, Clone, Copy)]
struct Row {
    link: Option<(usize, f64)>,
    extra: Option<(usize, f64)>,
    c: f64,
}

/// How the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Status {
    /// The caller's stopping rule holds.
    Converged,
    /// The duality gap stopped decreasing (numerical limit reached first).
    Stalled,
    /// The Schur complement could not be factorised.
    Breakdown,
    /// The iteration limit was reached.
    MaxIterations,
}

/// Bounds at an iterate, handed to the caller's stopping rule.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    /// `bᵀy` (a lower bound on the optimum: `y` is strictly feasible).
    pub dobj: f64,
    /// `bᵀy + ⟨X, S⟩ + |yᵀ(b − A(X))|`: an upper bound on the optimum. (Weak duality gives
    /// `⟨C, X⟩ = bᵀy + ⟨X, S⟩ − yᵀ(b − A(X))` for the dual-feasible `y`, an upper bound when
    /// `A(X) = b`; the residual term covers the round-off in `A(X) = b`, with `y` standing in for
    /// the optimal `y*`.)
    pub upper: f64,
    /// Relative primal infeasibility `‖b − A(X)‖ / (1 + ‖b‖)`.
    pub pinf: f64,
}

/// A primal iterate `(X_j, x)`.
#[derive(Debug, Clone)]
pub(crate) struct Primal {
    /// PSD blocks.
    pub x: Vec<DMatrix<f64>>,
    /// LP part.
    pub xl: DVector<f64>,
}

/// Result of a solve: the last (strictly dual-feasible) iterate and how the solve ended.
#[derive(Debug, Clone)]
pub(crate) struct Outcome {
    /// `y = (c, e)`.
    pub y: DVector<f64>,
    /// Bounds at `y`.
    pub bounds: Bounds,
    /// Iterations (each one factorisation of the Schur complement).
    pub iterations: usize,
    /// Why it stopped.
    pub status: Status,
    /// The last primal iterate (for a warm start).
    pub primal: Primal,
}

/// The problems of the primal–dual method: the three shared [`Mode`]s and the ratio form.
#[derive(Debug, Clone)]
enum Kind {
    Condition,
    /// `max −t` s.t. `Π ⪯ L(w) ⪯ t Π`: the conditioning SDP in the scale `λ_min = 1`, where a
    /// relative duality gap is a relative accuracy of the ratio `t = λ_max/λ_min` however
    /// small `s = 1/t` is.
    Ratio,
    Gap {
        wmax: f64,
    },
    L1,
}

/// A stress SDP in the form above.
pub(crate) struct Problem<'a> {
    space: &'a StressSpace,
    kind: Kind,
    blocks: Vec<Block>,
    rows: Vec<Row>,
    /// Number of extra variables `e`.
    ne: usize,
    /// `e` is one scalar kept in the Schur system (else: diagonal, eliminated).
    keep_extra: bool,
    /// Objective `b` (maximised).
    b: DVector<f64>,
    /// `Π = I − J`.
    pi: DMatrix<f64>,
}

/// Per-iteration factorisations of one PSD block.
struct Factored {
    /// `S` (on the complement).
    s: DMatrix<f64>,
    /// Cholesky factor of `S + J`.
    chol: Cholesky<f64, Dyn>,
    /// `S⁺ = (S + J)⁻¹ − J`.
    inv: DMatrix<f64>,
}

impl<'a> Problem<'a> {
    /// Sets up `mode` on `space`.
    pub fn new(space: &'a StressSpace, mode: &Mode) -> Self {
        let m = space.z.ncols();
        let nl = space.links.len();
        let blk = |sigma, gamma, eta| Block { sigma, gamma, eta };
        let kind = match mode {
            Mode::Condition => Kind::Condition,
            Mode::Gap { wmax, .. } => Kind::Gap { wmax: *wmax },
            Mode::L1 { .. } => Kind::L1,
        };
        let (blocks, rows, ne, keep_extra) = match mode {
            Mode::Condition => (
                vec![blk(1.0, 0.0, 1.0), blk(-1.0, 1.0, 0.0)],
                vec![],
                1,
                true,
            ),
            Mode::Gap { lambda_bar, wmax } => {
                let mut rows = vec![Row {
                    link: None,
                    extra: Some((0, 1.0)),
                    c: *lambda_bar,
                }];
                for l in 0..nl {
                    for rho in [1.0, -1.0] {
                        rows.push(Row {
                            link: Some((l, rho)),
                            extra: None,
                            c: *wmax,
                        });
                    }
                }
                (vec![blk(1.0, 0.0, 1.0)], rows, 1, true)
            }
            Mode::L1 { kappa, penalised } => {
                let mut rows = Vec::new();
                let mut k = 0;
                for (l, &p) in penalised.iter().enumerate() {
                    if p {
                        // p_k − w_l ≥ 0 and p_k + w_l ≥ 0.
                        for rho in [1.0, -1.0] {
                            rows.push(Row {
                                link: Some((l, rho)),
                                extra: Some((k, -1.0)),
                                c: 0.0,
                            });
                        }
                        k += 1;
                    }
                }
                (
                    vec![blk(1.0, -1.0, 0.0), blk(-1.0, *kappa, 0.0)],
                    rows,
                    k,
                    false,
                )
            }
        };
        let mut b = DVector::zeros(m + ne);
        match mode {
            Mode::Condition | Mode::Gap { .. } => b[m] = 1.0,
            Mode::L1 { .. } => b.rows_mut(m, ne).fill(-1.0),
        }
        let pi = space.pi();
        Self {
            space,
            kind,
            blocks,
            rows,
            ne,
            keep_extra,
            b,
            pi,
        }
    }

    /// The ratio form `max −t` s.t. `Π ⪯ L(w) ⪯ t Π` on `space`; `y = (c, t)`.
    pub fn ratio(space: &'a StressSpace) -> Self {
        let m = space.z.ncols();
        let mut b = DVector::zeros(m + 1);
        b[m] = -1.0;
        Self {
            space,
            kind: Kind::Ratio,
            blocks: vec![
                Block {
                    sigma: 1.0,
                    gamma: -1.0,
                    eta: 0.0,
                },
                Block {
                    sigma: -1.0,
                    gamma: 0.0,
                    eta: -1.0,
                },
            ],
            rows: Vec::new(),
            ne: 1,
            keep_extra: true,
            b,
            pi: space.pi(),
        }
    }

    fn m(&self) -> usize {
        self.space.z.ncols()
    }

    /// Weights `w = Z c` of `y`.
    pub fn weights(&self, y: &DVector<f64>) -> DVector<f64> {
        &self.space.z * y.rows(0, self.m())
    }

    /// `bᵀy`.
    pub fn objective(&self, y: &DVector<f64>) -> f64 {
        self.b.dot(y)
    }

    fn e0(&self, y: &DVector<f64>) -> f64 {
        if self.keep_extra {
            y[self.m()]
        } else {
            0.0
        }
    }

    /// PSD slacks (dense, on the complement) and LP slacks at `y`.
    fn slacks(&self, y: &DVector<f64>) -> (Vec<DMatrix<f64>>, DVector<f64>) {
        let w = self.weights(y);
        let lw = self.space.laplacian(w.as_slice());
        let e0 = self.e0(y);
        let psd = self
            .blocks
            .iter()
            .map(|b| &lw * b.sigma + &self.pi * (b.gamma - b.eta * e0))
            .collect();
        let lp = self.row_values(&w, y, |r| r.c, -1.0);
        (psd, lp)
    }

    /// `base(r) + sign (ρ w_l + ε e_k)` for every LP row.
    fn row_values(
        &self,
        w: &DVector<f64>,
        y: &DVector<f64>,
        base: impl Fn(&Row) -> f64,
        sign: f64,
    ) -> DVector<f64> {
        let m = self.m();
        DVector::from_iterator(
            self.rows.len(),
            self.rows.iter().map(|r| {
                let mut v = 0.0;
                if let Some((l, rho)) = r.link {
                    v += rho * w[l];
                }
                if let Some((k, eps)) = r.extra {
                    v += eps * y[m + k];
                }
                base(r) + sign * v
            }),
        )
    }

    /// `ΔS = −A*(Δy)`: PSD parts as the pair (`Δw`, `Δe₀`) and LP parts.
    fn dual_step(&self, dy: &DVector<f64>) -> (DVector<f64>, f64, DVector<f64>) {
        let dw = self.weights(dy);
        let de0 = self.e0(dy);
        let lp = self.row_values(&dw, dy, |_| 0.0, -1.0);
        (dw, de0, lp)
    }

    /// Dense `ΔS_j` of block `b`.
    fn block_step(&self, b: &Block, ldw: &DMatrix<f64>, de0: f64) -> DMatrix<f64> {
        ldw * b.sigma - &self.pi * (b.eta * de0)
    }

    /// `A(Y)` in `y`-space for PSD parts given through `gd(Y_j)` (the gathered diagonal
    /// `b_lᵀ Y_j b_l`) and `tr(Y_j)`, and an LP vector.
    fn a_op(&self, gd: &[DVector<f64>], tr: &[f64], lp: &DVector<f64>) -> DVector<f64> {
        let m = self.m();
        let nl = self.space.links.len();
        let mut gw = DVector::zeros(nl);
        let mut ge = DVector::zeros(self.ne);
        for (j, b) in self.blocks.iter().enumerate() {
            gw.axpy(-b.sigma, &gd[j], 1.0);
            if self.keep_extra {
                ge[0] += b.eta * tr[j];
            }
        }
        for (r, row) in self.rows.iter().enumerate() {
            if let Some((l, rho)) = row.link {
                gw[l] += rho * lp[r];
            }
            if let Some((k, eps)) = row.extra {
                ge[k] += eps * lp[r];
            }
        }
        let mut out = DVector::zeros(m + self.ne);
        out.rows_mut(0, m).copy_from(&(self.space.z.tr_mul(&gw)));
        out.rows_mut(m, self.ne).copy_from(&ge);
        out
    }

    /// A strictly feasible primal start `X ≻ 0`, `x > 0` with `A(X) = b`, roughly centred on
    /// the dual start's slacks (constructed per mode; see the module docs).
    fn primal_start(
        &self,
        s: &[DMatrix<f64>],
        sl: &DVector<f64>,
    ) -> (Vec<DMatrix<f64>>, DVector<f64>) {
        let np = self.space.np() as f64;
        match &self.kind {
            // A_c(X) = Zᵀ gd(X₂ − X₁) = 0 and tr X₁ = 1 (Ratio: tr X₂ = 1).
            Kind::Condition | Kind::Ratio => {
                (vec![&self.pi / np, &self.pi / np], DVector::zeros(0))
            }
            // A_c(X) = Zᵀ(x₊ − x₋ − gd(X₁)) = 0 and tr X₁ + x_λ = 1.
            Kind::Gap { wmax } => {
                let xi = 0.5 / np;
                let x1 = &self.pi * xi;
                let gd = self.space.gather_diag(&x1);
                let lam1 = s[0].trace() / np;
                let mut xl = DVector::zeros(self.rows.len());
                xl[0] = 0.5;
                let delta = xi * lam1 / wmax;
                for (l, g) in gd.iter().enumerate() {
                    xl[1 + 2 * l] = g + delta;
                    xl[2 + 2 * l] = delta;
                }
                (vec![x1], xl)
            }
            // A_c(X) = Zᵀ(gd(X₂ − X₁) + x₁ − x₂) = 0 and x₁ + x₂ = 1 per p.
            Kind::L1 => {
                let mean_lp = sl.mean();
                let mean_eig = (s[0].trace() + s[1].trace()) / (2.0 * np);
                let xi = 0.5 * mean_lp / mean_eig.max(f64::MIN_POSITIVE);
                (
                    vec![&self.pi * xi, &self.pi * xi],
                    DVector::from_element(self.rows.len(), 0.5),
                )
            }
        }
    }

    fn factor(&self, s: DMatrix<f64>) -> Option<Factored> {
        let j = self.space.affine_projector();
        let chol = dense::cholesky(&s + j)?;
        let inv = dense::spd_inverse(&chol) - j;
        Some(Factored { s, chol, inv })
    }
}

/// Largest `α` with `M + α ΔM ⪰ 0` on the complement (`∞` if every α works), for `M ≻ 0` there
/// with Cholesky factor `F` of `M + J`: `1 / max(0, −λ_min(F⁻¹ ΔM F⁻ᵀ))`.
fn max_step_psd(chol: &Cholesky<f64, Dyn>, dm: &DMatrix<f64>) -> f64 {
    let lam = dense::min_eig_congruence(chol, dm);
    if lam < 0.0 {
        -1.0 / lam
    } else {
        f64::INFINITY
    }
}

fn max_step_lp(x: &DVector<f64>, dx: &DVector<f64>) -> f64 {
    x.iter()
        .zip(dx.iter())
        .filter(|(_, &d)| d < 0.0)
        .map(|(&v, &d)| -v / d)
        .fold(f64::INFINITY, f64::min)
}

/// Solves `H y = r` for symmetric positive definite `H`, with retries under diagonal shifts of
/// 1e-14 and 1e-10 of the largest diagonal entry (below the accuracy asked of a step).
fn solve_spd(h: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = h.nrows();
    let dmax = h.diagonal().amax().max(f64::MIN_POSITIVE);
    if let Some(ch) = dense::cholesky(h.clone()) {
        return Some(ch);
    }
    for shift in [1e-14, 1e-10] {
        if let Some(ch) = dense::cholesky(&h + DMatrix::<f64>::identity(n, n) * (shift * dmax)) {
            return Some(ch);
        }
    }
    None
}

/// Runs the method from the strictly feasible `y0` (and the primal `x0`, or the feasible start
/// of the mode) until `stop(y, bounds)` holds or the method stops by itself (see the module
/// docs).
///
/// Returns `None` only if `y0` is not strictly feasible.
pub(crate) fn solve(
    problem: &Problem<'_>,
    y0: DVector<f64>,
    x0: Option<Primal>,
    stop: impl Fn(&DVector<f64>, &Bounds) -> bool,
) -> Option<Outcome> {
    const MAX_ITER: usize = 150;
    let space = problem.space;
    let nb = problem.blocks.len();
    let nu = (nb * space.np() + problem.rows.len()) as f64;

    let Iterate {
        mut y,
        mut sl,
        mut fac,
        mut x,
        mut xl,
        mut xchol,
    } = Iterate::start(problem, y0, x0)?;
    let jproj = space.affine_projector();
    let mut bounds = bounds_at(problem, &y, &x, &xl, &fac, &sl);
    let mut watch = Watch::default();
    let mut iterations = 0;
    let finish = |y, bounds, iterations, status, x, xl| Outcome {
        y,
        bounds,
        iterations,
        status,
        primal: Primal { x, xl },
    };
    loop {
        if stop(&y, &bounds) {
            return Some(finish(y, bounds, iterations, Status::Converged, x, xl));
        }
        if iterations >= MAX_ITER {
            return Some(finish(y, bounds, iterations, Status::MaxIterations, x, xl));
        }
        if watch.stalled(&bounds) {
            return Some(finish(y, bounds, iterations, Status::Stalled, x, xl));
        }
        iterations += 1;

        // μ and the Schur complement.
        let mu = (x
            .iter()
            .zip(&fac)
            .fold(0.0, |xs, (xj, f)| xs + xj.dot(&f.s))
            + xl.dot(&sl))
            / nu;
        let ratio = xl.component_div(&sl);
        let Some(schur) = schur(problem, &x, &fac, &ratio) else {
            return Some(finish(y, bounds, iterations, Status::Breakdown, x, xl));
        };
        let at = Point {
            x: &x,
            xl: &xl,
            fac: &fac,
            sl: &sl,
        };
        let (step, ap, ad) = predictor_corrector(problem, &schur, &at, &xchol, (mu, nu));
        watch.tiny_steps = if ap < 1e-9 && ad < 1e-9 {
            watch.tiny_steps + 1
        } else {
            0
        };
        let (Some((xn, xl_n, ch)), Some((y_new, sl_new, f))) = (
            primal_update(&x, &xl, &step, ap, jproj),
            dual_update(problem, &y, &step, ad),
        ) else {
            // Round-off puts every step on the boundary: keep the last (feasible) iterate.
            return Some(finish(y, bounds, iterations, Status::Stalled, x, xl));
        };
        (x, xl, xchol) = (xn, xl_n, ch);
        (y, sl, fac) = (y_new, sl_new, f);
        bounds = bounds_at(problem, &y, &x, &xl, &fac, &sl);
    }
}

/// A primal–dual iterate: `y` with its slacks (LP part `sl`, PSD blocks factorised), and
/// `(X, x)` with the Cholesky factors of `X_j + J`.
struct Iterate {
    y: DVector<f64>,
    sl: DVector<f64>,
    fac: Vec<Factored>,
    x: Vec<DMatrix<f64>>,
    xl: DVector<f64>,
    xchol: Vec<Cholesky<f64, Dyn>>,
}

impl Iterate {
    /// The start: `y0` (`None` unless strictly feasible) and `x0`, or the mode's feasible
    /// primal start.
    fn start(problem: &Problem<'_>, y0: DVector<f64>, x0: Option<Primal>) -> Option<Self> {
        let (s0, sl) = problem.slacks(&y0);
        if sl.iter().any(|&v| v <= 0.0) {
            return None;
        }
        let mut fac: Vec<Factored> = Vec::with_capacity(problem.blocks.len());
        for s in s0 {
            fac.push(problem.factor(s)?);
        }
        let (x, xl) = match x0 {
            Some(p) => (p.x, p.xl),
            None => {
                let s: Vec<DMatrix<f64>> = fac.iter().map(|f| f.s.clone()).collect();
                problem.primal_start(&s, &sl)
            }
        };
        let jproj = problem.space.affine_projector();
        let xchol = x
            .iter()
            .map(|xj| dense::cholesky(xj + jproj))
            .collect::<Option<Vec<_>>>()?;
        Some(Self {
            y: y0,
            sl,
            fac,
            x,
            xl,
            xchol,
        })
    }
}

/// The bounds at the iterate `(y, X, x)` with its dual slacks.
fn bounds_at(
    problem: &Problem<'_>,
    y: &DVector<f64>,
    x: &[DMatrix<f64>],
    xl: &DVector<f64>,
    fac: &[Factored],
    sl: &DVector<f64>,
) -> Bounds {
    let space = problem.space;
    let gd: Vec<DVector<f64>> = x.iter().map(|xj| space.gather_diag(xj)).collect();
    let tr: Vec<f64> = x.iter().map(|xj| xj.trace()).collect();
    let rp = &problem.b - problem.a_op(&gd, &tr, xl);
    let mut compl = xl.dot(sl);
    for (xj, f) in x.iter().zip(fac) {
        compl += xj.dot(&f.s);
    }
    let dobj = problem.objective(y);
    Bounds {
        dobj,
        upper: dobj + compl.max(0.0) + y.dot(&rp).abs(),
        pinf: rp.norm() / (1.0 + problem.b.norm()),
    }
}

/// When the method stops by itself: the gap not halved for 8 iterations, two tiny steps in a
/// row, the primal infeasibility above [`PINF`] for 3, or the dual objective frozen with the
/// gap not shrinking (the numerical limit).
struct Watch {
    best_gap: f64,
    since_best: usize,
    tiny_steps: usize,
    lost_primal: usize,
    dobj_hist: Vec<f64>,
}

impl Default for Watch {
    fn default() -> Self {
        Self {
            best_gap: f64::INFINITY,
            since_best: 0,
            tiny_steps: 0,
            lost_primal: 0,
            dobj_hist: Vec::new(),
        }
    }
}

impl Watch {
    /// Records the bounds of this iterate; whether the method has stalled.
    fn stalled(&mut self, bounds: &Bounds) -> bool {
        let gap = bounds.upper - bounds.dobj;
        if gap < 0.5 * self.best_gap {
            self.best_gap = gap;
            self.since_best = 0;
        } else {
            self.since_best += 1;
        }
        if bounds.pinf > PINF {
            self.lost_primal += 1;
        } else {
            self.lost_primal = 0;
        }
        self.dobj_hist.push(bounds.dobj);
        let h = &self.dobj_hist;
        let k = h.len();
        // The dual objective stopped moving and the gap stopped shrinking: the numerical limit.
        let frozen = k > 3
            && (h[k - 1] - h[k - 4]).abs() <= 1e-10 * bounds.dobj.abs()
            && self.since_best >= 3;
        self.since_best >= 8 || self.tiny_steps >= 2 || self.lost_primal >= 3 || frozen
    }
}

/// Mehrotra's predictor–corrector at `at`: the affine direction (`M Δy = b`), the centring
/// `σ = (μ_a / μ)³`, and the corrected direction with the second-order term `ΔX_a ΔS_a S⁻¹`;
/// returns it with its primal and dual step lengths (a share γ of the way to the boundary).
fn predictor_corrector(
    problem: &Problem<'_>,
    schur: &Schur,
    at: &Point<'_>,
    xchol: &[Cholesky<f64, Dyn>],
    (mu, nu): (f64, f64),
) -> (Step, f64, f64) {
    let space = problem.space;
    let (x, xl, fac, sl) = (at.x, at.xl, at.fac, at.sl);
    // Predictor: M Δy = b.
    let step_a = refined_step(problem, schur, at, &problem.b, 0.0, None);
    let ap = step_a.max_primal(xchol, xl).min(1.0);
    let ad = step_a.max_dual(fac, sl).min(1.0);
    let mut xs_a = 0.0;
    for j in 0..problem.blocks.len() {
        let xa = &x[j] + &step_a.dx[j] * ap;
        let sa = &fac[j].s + &step_a.ds[j] * ad;
        xs_a += xa.dot(&sa);
    }
    xs_a += (xl + &step_a.dxl * ap).dot(&(sl + &step_a.dsl * ad));
    let sigma = ((xs_a / nu) / mu).clamp(0.0, 1.0).powi(3);

    // Corrector with the second-order term ΔX_a ΔS_a S⁻¹.
    let (dw_a, de0_a, _) = problem.dual_step(&step_a.dy);
    let corr: Vec<DMatrix<f64>> = problem
        .blocks
        .iter()
        .enumerate()
        .map(|(j, b)| {
            let t = space.mul_slack_step(&step_a.dx[j], b.sigma, dw_a.as_slice(), -b.eta * de0_a);
            dense::par_mul(&t, &fac[j].inv)
        })
        .collect();
    let corr_l = step_a.dxl.component_mul(&step_a.dsl).component_div(sl);
    let gd_inv: Vec<DVector<f64>> = fac.iter().map(|f| space.gather_diag(&f.inv)).collect();
    let tr_inv: Vec<f64> = fac.iter().map(|f| f.inv.trace()).collect();
    let inv_l = sl.map(|v| 1.0 / v);
    let gd_corr: Vec<DVector<f64>> = corr.iter().map(|c| space.gather_diag(c)).collect();
    let tr_corr: Vec<f64> = corr.iter().map(|c| c.trace()).collect();
    let rhs = &problem.b - problem.a_op(&gd_inv, &tr_inv, &inv_l) * (sigma * mu)
        + problem.a_op(&gd_corr, &tr_corr, &corr_l);
    let step = refined_step(problem, schur, at, &rhs, sigma * mu, Some((&corr, &corr_l)));
    let gamma = (0.9 + 0.09 * ap.min(ad)).min(0.99);
    let ap = (gamma * step.max_primal(xchol, xl)).min(1.0);
    let ad = (gamma * step.max_dual(fac, sl)).min(1.0);
    (step, ap, ad)
}

/// The primal update `(X, x) + a (ΔX, Δx)`, checked by a factorisation of each `X_j + J` (the
/// Lanczos step length can overshoot the boundary slightly) and shortened by 0.8 until it
/// passes; `None` after 30 tries.
#[allow(clippy::type_complexity)]
fn primal_update(
    x: &[DMatrix<f64>],
    xl: &DVector<f64>,
    step: &Step,
    mut ap: f64,
    jproj: &DMatrix<f64>,
) -> Option<(Vec<DMatrix<f64>>, DVector<f64>, Vec<Cholesky<f64, Dyn>>)> {
    for _ in 0..30 {
        let xn: Vec<DMatrix<f64>> = (0..x.len())
            .map(|j| dense::symmetrise(&x[j] + &step.dx[j] * ap))
            .collect();
        let xl_n = xl + &step.dxl * ap;
        let ch = xn
            .iter()
            .map(|m| dense::cholesky(m + jproj))
            .collect::<Option<Vec<_>>>();
        match ch {
            Some(ch) if xl_n.iter().all(|&v| v > 0.0) => return Some((xn, xl_n, ch)),
            _ => ap *= 0.8,
        }
    }
    None
}

/// The dual update `y + a Δy`, its slacks recomputed from it (no drift) and factorised,
/// shortened by 0.8 until they are positive definite; `None` after 30 tries.
fn dual_update(
    problem: &Problem<'_>,
    y: &DVector<f64>,
    step: &Step,
    mut ad: f64,
) -> Option<(DVector<f64>, DVector<f64>, Vec<Factored>)> {
    for _ in 0..30 {
        let y_new = y + &step.dy * ad;
        let (s_new, sl_new) = problem.slacks(&y_new);
        if sl_new.iter().all(|&v| v > 0.0) {
            let f = s_new
                .into_iter()
                .map(|s| problem.factor(s))
                .collect::<Option<Vec<_>>>();
            if let Some(f) = f {
                return Some((y_new, sl_new, f));
            }
        }
        ad *= 0.8;
    }
    None
}

/// The factorised Schur complement.
struct Schur {
    chol: Cholesky<f64, Dyn>,
    /// Eliminated extras (L1): per extra `k`, its link, `h_ee` and `h_we`.
    elim: Vec<(usize, f64, f64)>,
}

impl Schur {
    /// Solves `M Δy = r`.
    fn solve(&self, problem: &Problem<'_>, r: &DVector<f64>) -> DVector<f64> {
        let m = problem.m();
        let z = &problem.space.z;
        if problem.keep_extra {
            return self.chol.solve(r);
        }
        // r_c − Zᵀ (h_we h_ee⁻¹ r_e), then back-substitute Δe.
        let mut tw = DVector::zeros(z.nrows());
        for (k, &(l, hee, hwe)) in self.elim.iter().enumerate() {
            tw[l] += hwe * r[m + k] / hee;
        }
        let rc = r.rows(0, m) - z.tr_mul(&tw);
        let dc = self.chol.solve(&rc);
        let dw = z * &dc;
        let mut out = DVector::zeros(m + problem.ne);
        out.rows_mut(0, m).copy_from(&dc);
        for (k, &(l, hee, hwe)) in self.elim.iter().enumerate() {
            out[m + k] = (r[m + k] - hwe * dw[l]) / hee;
        }
        out
    }
}

/// Assembles and factorises the Schur complement (see the module docs); `ratio = x / s` of the
/// LP rows.
fn schur(
    problem: &Problem<'_>,
    x: &[DMatrix<f64>],
    fac: &[Factored],
    ratio: &DVector<f64>,
) -> Option<Schur> {
    let space = problem.space;
    let m = problem.m();
    let nl = space.links.len();
    let pairs: Vec<(&DMatrix<f64>, &DMatrix<f64>)> =
        x.iter().zip(fac).map(|(xj, f)| (xj, &f.inv)).collect();
    let mut h = space.hadamard_gram(&pairs);
    // LP rows: ρ² x/s on the diagonal; couplings to the extras.
    let mut hwe = DVector::zeros(nl);
    let mut hee = DVector::zeros(problem.ne);
    let mut link_of_extra = vec![usize::MAX; problem.ne];
    for (r, row) in problem.rows.iter().enumerate() {
        let d = ratio[r];
        if let Some((l, rho)) = row.link {
            h[(l, l)] += rho * rho * d;
            if let Some((k, eps)) = row.extra {
                if problem.keep_extra {
                    hwe[l] += rho * eps * d;
                } else {
                    link_of_extra[k] = l;
                }
            }
        }
        if let Some((k, eps)) = row.extra {
            hee[k] += eps * eps * d;
        }
    }
    let mut elim = Vec::new();
    if problem.keep_extra {
        for (j, b) in problem.blocks.iter().enumerate() {
            if b.eta != 0.0 {
                let gd = space.gather_diag_product(&x[j], &fac[j].inv);
                hwe.axpy(-b.sigma * b.eta, &gd, 1.0);
                hee[0] += b.eta * b.eta * x[j].dot(&fac[j].inv);
            }
        }
    } else {
        // Eliminate each extra: its rows touch one link only.
        let mut hwe_k = vec![0.0; problem.ne];
        for (r, row) in problem.rows.iter().enumerate() {
            if let (Some((_, rho)), Some((k, eps))) = (row.link, row.extra) {
                hwe_k[k] += rho * eps * ratio[r];
            }
        }
        for k in 0..problem.ne {
            let l = link_of_extra[k];
            h[(l, l)] -= hwe_k[k] * hwe_k[k] / hee[k];
            elim.push((l, hee[k], hwe_k[k]));
        }
    }
    let z = &space.z;
    let hz = dense::par_mul(&h, z);
    let mcc = dense::par_mul_tr(z, &hz);
    let ny = if problem.keep_extra { m + 1 } else { m };
    let mut mat = DMatrix::zeros(ny, ny);
    mat.view_mut((0, 0), (m, m)).copy_from(&mcc);
    if problem.keep_extra {
        let mce = z.tr_mul(&hwe);
        mat.view_mut((0, m), (m, 1)).copy_from(&mce);
        mat.view_mut((m, 0), (1, m)).copy_from(&mce.transpose());
        mat[(m, m)] = hee[0];
    }
    // Symmetrise against round-off in the two products.
    let t = mat.transpose();
    mat += t;
    mat *= 0.5;
    let chol = solve_spd(mat)?;
    Some(Schur { chol, elim })
}

/// Search directions for one right-hand side.
struct Step {
    dy: DVector<f64>,
    dx: Vec<DMatrix<f64>>,
    dxl: DVector<f64>,
    ds: Vec<DMatrix<f64>>,
    dsl: DVector<f64>,
    /// `M Δy` evaluated through the matrices, `A(X A*(Δy) S⁻¹)`, for iterative refinement.
    m_dy: DVector<f64>,
}

impl Step {
    fn max_primal(&self, xchol: &[Cholesky<f64, Dyn>], xl: &DVector<f64>) -> f64 {
        let mut a = max_step_lp(xl, &self.dxl);
        for (c, d) in xchol.iter().zip(&self.dx) {
            a = a.min(max_step_psd(c, d));
        }
        a
    }
    fn max_dual(&self, fac: &[Factored], sl: &DVector<f64>) -> f64 {
        let mut a = max_step_lp(sl, &self.dsl);
        for (f, d) in fac.iter().zip(&self.ds) {
            a = a.min(max_step_psd(&f.chol, d));
        }
        a
    }
}

/// The iterate and its factorised slacks, as the direction computations need them.
struct Point<'p> {
    x: &'p [DMatrix<f64>],
    xl: &'p DVector<f64>,
    fac: &'p [Factored],
    sl: &'p DVector<f64>,
}

/// Solves `M Δy = rhs` and forms the directions, with one step of iterative refinement
/// against `A(X A*(Δy) S⁻¹)` evaluated through the matrices (near the optimum `M` is
/// ill-conditioned, and the primal residual `A(ΔX) − R_p` is exactly the solve's residual).
fn refined_step(
    problem: &Problem<'_>,
    schur: &Schur,
    at: &Point<'_>,
    rhs: &DVector<f64>,
    sigma_mu: f64,
    corr: Option<(&Vec<DMatrix<f64>>, &DVector<f64>)>,
) -> Step {
    let mut dy = schur.solve(problem, rhs);
    let mut step = directions(problem, at, dy.clone(), sigma_mu, corr);
    let rnorm = rhs.norm();
    {
        let r = rhs - &step.m_dy;
        if r.norm() > 1e-12 * rnorm {
            dy += schur.solve(problem, &r);
            step = directions(problem, at, dy.clone(), sigma_mu, corr);
        }
    }
    step
}

/// `ΔS = −A*(Δy)` and `ΔX = σμ S⁻¹ − X − sym(X ΔS S⁻¹ + corr)` (LP: the diagonal analogue).
fn directions(
    problem: &Problem<'_>,
    at: &Point<'_>,
    dy: DVector<f64>,
    sigma_mu: f64,
    corr: Option<(&Vec<DMatrix<f64>>, &DVector<f64>)>,
) -> Step {
    let space = problem.space;
    let Point { x, xl, fac, sl } = *at;
    let (dw, de0, dsl) = problem.dual_step(&dy);
    let ldw = space.laplacian(dw.as_slice());
    let mut dx = Vec::with_capacity(x.len());
    let mut ds = Vec::with_capacity(x.len());
    let mut gd = Vec::with_capacity(x.len());
    let mut tr = Vec::with_capacity(x.len());
    for (j, b) in problem.blocks.iter().enumerate() {
        let dsj = problem.block_step(b, &ldw, de0);
        // X ΔS S⁻¹ (X ΔS through the sparse L(Δw)); −A of it is M Δy.
        let xds = space.mul_slack_step(&x[j], b.sigma, dw.as_slice(), -b.eta * de0);
        let mut t = dense::par_mul(&xds, &fac[j].inv);
        gd.push(-space.gather_diag(&t));
        tr.push(-t.trace());
        if let Some((c, _)) = corr {
            t += &c[j];
        }
        let mut dxj = &fac[j].inv * sigma_mu - &x[j];
        dxj -= (&t + t.transpose()) * 0.5;
        dx.push(dxj);
        ds.push(dsj);
    }
    let xds = xl.component_mul(&dsl).component_div(sl);
    let m_dy = problem.a_op(&gd, &tr, &(-&xds));
    let mut dxl = sl.map(|v| sigma_mu / v) - xl - xds;
    if let Some((_, cl)) = corr {
        dxl -= cl;
    }
    Step {
        dy,
        dx,
        dxl,
        ds,
        dsl,
        m_dy,
    }
}

/// Result of [`solve_robust`]: the best strictly feasible iterate found and the bounds on the
/// optimum `max bᵀy`.
#[derive(Debug, Clone)]
pub(crate) struct Solved {
    /// The iterate (strictly feasible: a valid design).
    pub y: DVector<f64>,
    /// `bᵀy`.
    pub lower: f64,
    /// The smallest certified upper bound on the optimum (∞ if none).
    pub upper: f64,
    /// Iterations of both methods.
    pub iterations: usize,
    /// Which method produced `y`.
    pub solver: &'static str,
}

/// Relative primal infeasibility `‖b − A(X)‖ / (1 + ‖b‖)` up to which the bound
/// [`Bounds::upper`] is used. `A(X) = b` holds at the feasible start; near the optimum the
/// Schur complement is ill-conditioned and the residual grows (measured: to 1e-5 when
/// `λ_max/λ_min ≈ 3·10⁴`), which the term `|yᵀ(b − A(X))|` of the bound accounts for.
pub(crate) const PINF: f64 = 1e-4;

/// Solves `mode` from the strictly feasible `y0` by the primal–dual method and, if it stops
/// without `accept(lower, upper)`, by the barrier method of [`super::barrier`] (from the
/// primal–dual iterate, or from `y0` if the barrier's own test finds that iterate on the
/// boundary). Returns the better of the two iterates and the best of their upper bounds.
///
/// # Errors
/// [`super::SolverStatus::NumericalBreakdown`] when `y0` is not strictly feasible.
pub(crate) fn solve_robust(
    space: &StressSpace,
    mode: Mode,
    y0: DVector<f64>,
    accept: impl Fn(f64, f64) -> bool,
) -> Result<Solved, super::DesignError> {
    let problem = Problem::new(space, &mode);
    let out = solve(&problem, y0.clone(), None, |_, b| {
        b.pinf <= PINF && accept(b.dobj, b.upper)
    })
    .ok_or(super::DesignError::Solver {
        status: super::SolverStatus::NumericalBreakdown,
        iterations: 0,
    })?;
    let mut best = Solved {
        lower: out.bounds.dobj,
        upper: if out.bounds.pinf <= PINF {
            out.bounds.upper
        } else {
            f64::INFINITY
        },
        y: out.y,
        iterations: out.iterations,
        solver: "primal-dual",
    };
    if out.status == Status::Converged {
        return Ok(best);
    }
    let bp = super::barrier::Problem::new(space, mode);
    let bstop = |x: &DVector<f64>, gap: f64| {
        let lo = -bp.objective(x);
        accept(lo, lo + gap)
    };
    let budget = if out.status == Status::Breakdown {
        super::barrier::RESCUE_STEPS
    } else {
        super::barrier::POLISH_STEPS
    };
    let fallback = super::barrier::solve(&bp, best.y.clone(), budget, bstop)
        .or_else(|| super::barrier::solve(&bp, y0, budget, bstop));
    if let Some(fb) = fallback {
        best.iterations += fb.newton_steps;
        best.upper = best.upper.min(-fb.lower_bound);
        let lo = -bp.objective(&fb.x);
        if lo > best.lower {
            best.lower = lo;
            best.y = fb.x;
            best.solver = "barrier (fallback)";
        }
    }
    Ok(best)
}
