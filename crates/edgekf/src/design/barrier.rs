//! The fallback solver: a primal log-barrier method (damped Newton) for the stress SDPs, used
//! when the primal–dual method of [`super::ipm`] stops without the requested accuracy.
//!
//! Every design problem here constrains `M(c) = Q L(Z c) Qᵀ = Σ_l w_l u_l u_lᵀ` with `w = Z c`
//! (see [`super::StressSpace`]): each constraint matrix is rank one. For `S = M(c) − s I` and
//! `W = S⁻¹`, the barrier `−log det S` has, in weight space,
//! gradient `−u_lᵀ W u_l` and Hessian `(u_lᵀ W u_k)²`, i.e. `G ∘ G` with `G = Uᵀ W U`
//! (L × L, cost `O(n' L²)`), instead of the `O(m² n'²)` traces of a general SDP solver; the
//! Newton matrix in `c` is `Zᵀ (G ∘ G) Z`.
//!
//! The method is the barrier method of Boyd & Vandenberghe, *Convex Optimization*, §11.3:
//! minimise `τ fᵀx + φ(x)` by damped Newton steps with a backtracking line search that keeps
//! every iterate strictly feasible, then raise `τ` by `μ = 10`. After centring, the duality gap
//! is at most `ν / τ` (ν = the barrier parameter, §11.2.2), which is what we stop on.
//!
//! Three problems share the code (all variables `x = (c, …)`):
//! - [`Mode::Condition`]: `max s` s.t. `s I ⪯ M(c) ⪯ I` — best conditioning; strictly feasible
//!   start `c = 0, s = −1`, and `s* ≤ 0` certifies that no PSD stress of full rank exists;
//! - [`Mode::Gap`]: `max s` s.t. `s I ⪯ M(c)`, `s ≤ λ̄`, `|w_l| ≤ w̄` — thesis (3.5) with
//!   bounded weights;
//! - [`Mode::L1`]: `min Σ p_l` s.t. `I ⪯ M(c) ⪯ κ̄ I`, `|w_l| ≤ p_l` for the penalised links —
//!   the sparse design; the `p` block is eliminated from the Newton system in closed form.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// Newton steps the barrier method may take when the primal–dual method found no usable point.
pub(crate) const RESCUE_STEPS: usize = 600;
/// Newton steps it may take to tighten the gap of a usable primal–dual point.
pub(crate) const POLISH_STEPS: usize = 100;
use super::{Mode, SolverStatus, StressSpace};

/// A barrier problem on a stress space.
pub(crate) struct Problem<'a> {
    space: &'a StressSpace,
    mode: Mode,
    /// For L1: link index of each `p` variable.
    pen_links: Vec<usize>,
    /// `U` (n' × L) of the stress space.
    u: DMatrix<f64>,
}

/// Result of a solve.
pub(crate) struct Outcome {
    /// The final iterate.
    pub x: DVector<f64>,
    /// Newton steps taken.
    pub newton_steps: usize,
    /// A lower bound on the minimum of `fᵀx`: `fᵀx_c − ν/τ` at the last centred iterate `x_c`
    /// (−∞ before the first).
    pub lower_bound: f64,
}

struct Lmi {
    w: DMatrix<f64>,
    logdet: f64,
}

fn inverse_logdet(s: DMatrix<f64>) -> Option<Lmi> {
    let chol = Cholesky::<f64, Dyn>::new(s)?;
    let logdet = 2.0
        * chol
            .l_dirty()
            .diagonal()
            .iter()
            .map(|v| v.ln())
            .sum::<f64>();
    Some(Lmi {
        w: chol.inverse(),
        logdet,
    })
}

impl<'a> Problem<'a> {
    pub fn new(space: &'a StressSpace, mode: Mode) -> Self {
        let pen_links = match &mode {
            Mode::L1 { penalised, .. } => (0..penalised.len()).filter(|&l| penalised[l]).collect(),
            _ => Vec::new(),
        };
        Self {
            space,
            mode,
            pen_links,
            u: space.u(),
        }
    }

    fn m(&self) -> usize {
        self.space.z.ncols()
    }

    fn links(&self) -> usize {
        self.space.z.nrows()
    }

    fn np(&self) -> usize {
        self.u.nrows()
    }

    /// Number of variables.
    pub fn dim(&self) -> usize {
        match self.mode {
            Mode::Condition | Mode::Gap { .. } => self.m() + 1,
            Mode::L1 { .. } => self.m() + self.pen_links.len(),
        }
    }

    /// Barrier parameter ν (sum of the cone degrees).
    pub fn nu(&self) -> f64 {
        let np = self.np() as f64;
        match self.mode {
            Mode::Condition => 2.0 * np,
            Mode::Gap { .. } => np + 1.0 + 2.0 * self.links() as f64,
            Mode::L1 { .. } => 2.0 * np + 2.0 * self.pen_links.len() as f64,
        }
    }

    /// Linear objective `fᵀx`.
    pub fn objective(&self, x: &DVector<f64>) -> f64 {
        match self.mode {
            Mode::Condition | Mode::Gap { .. } => -x[self.m()],
            Mode::L1 { .. } => x.rows(self.m(), self.pen_links.len()).sum(),
        }
    }

    /// Weights `w = Z c`.
    pub fn weights(&self, x: &DVector<f64>) -> DVector<f64> {
        &self.space.z * x.rows(0, self.m())
    }

    fn s_var(&self, x: &DVector<f64>) -> f64 {
        match self.mode {
            Mode::Condition | Mode::Gap { .. } => x[self.m()],
            Mode::L1 { .. } => 1.0,
        }
    }

    fn upper(&self) -> Option<f64> {
        match self.mode {
            Mode::Condition => Some(1.0),
            Mode::Gap { .. } => None,
            Mode::L1 { kappa, .. } => Some(kappa),
        }
    }

    /// The two LMI slacks at `x`, or `None` when `x` is not strictly feasible for them.
    fn lmis(&self, w: &DVector<f64>, s: f64) -> Option<(Lmi, Option<Lmi>)> {
        let mut uw = self.u.clone();
        for (l, &wl) in w.iter().enumerate() {
            uw.column_mut(l).scale_mut(wl);
        }
        let m = &uw * self.u.transpose();
        let n = m.nrows();
        let lo = inverse_logdet(&m - DMatrix::<f64>::identity(n, n) * s)?;
        let up = match self.upper() {
            Some(ub) => Some(inverse_logdet(DMatrix::<f64>::identity(n, n) * ub - &m)?),
            None => None,
        };
        Some((lo, up))
    }

    /// The barrier `φ(x)`, or `None` outside the interior.
    pub fn barrier(&self, x: &DVector<f64>) -> Option<f64> {
        let w = self.weights(x);
        let s = self.s_var(x);
        let (lo, up) = self.lmis(&w, s)?;
        let mut phi = -lo.logdet - up.map_or(0.0, |u| u.logdet);
        let log_pos = |v: f64| if v > 0.0 { Some(v.ln()) } else { None };
        match &self.mode {
            Mode::Condition => {}
            Mode::Gap { lambda_bar, wmax } => {
                phi -= log_pos(lambda_bar - s)?;
                for &wl in w.iter() {
                    phi -= log_pos(wmax - wl)? + log_pos(wmax + wl)?;
                }
            }
            Mode::L1 { .. } => {
                for (k, &l) in self.pen_links.iter().enumerate() {
                    let p = x[self.m() + k];
                    phi -= log_pos(p - w[l])? + log_pos(p + w[l])?;
                }
            }
        }
        Some(phi)
    }

    /// Newton step for `τ fᵀx + φ(x)` and the squared Newton decrement.
    pub fn newton(&self, x: &DVector<f64>, tau: f64) -> Result<(DVector<f64>, f64), SolverStatus> {
        let m = self.m();
        let nl = self.links();
        let w = self.weights(x);
        let s = self.s_var(x);
        let (lo, up) = self.lmis(&w, s).ok_or(SolverStatus::NumericalBreakdown)?;
        let u = &self.u;
        let wu_lo = &lo.w * u;
        let g_lo = u.transpose() * &wu_lo;
        let mut hww = g_lo.component_mul(&g_lo);
        let mut gw = DVector::from_iterator(nl, (0..nl).map(|l| -g_lo[(l, l)]));
        if let Some(up) = &up {
            let g_up = u.transpose() * (&up.w * u);
            hww += g_up.component_mul(&g_up);
            for l in 0..nl {
                gw[l] += g_up[(l, l)];
            }
        }
        // Right-hand side in weight space (−gradient, with the L1 block eliminated).
        let mut rw = -&gw;
        let mut l1_terms = Vec::new();
        match &self.mode {
            Mode::Condition => {}
            Mode::Gap { wmax, .. } => {
                for l in 0..nl {
                    let a = wmax - w[l];
                    let b = wmax + w[l];
                    gw[l] += 1.0 / a - 1.0 / b;
                    rw[l] -= 1.0 / a - 1.0 / b;
                    hww[(l, l)] += 1.0 / (a * a) + 1.0 / (b * b);
                }
            }
            Mode::L1 { .. } => {
                for (k, &l) in self.pen_links.iter().enumerate() {
                    let p = x[m + k];
                    let a = p - w[l];
                    let b = p + w[l];
                    let gwl = 1.0 / a - 1.0 / b;
                    let gp = tau - 1.0 / a - 1.0 / b;
                    let hd = 1.0 / (a * a) + 1.0 / (b * b);
                    let hws = 1.0 / (b * b) - 1.0 / (a * a);
                    gw[l] += gwl;
                    // Schur complement of the diagonal p block: hww − hws²/hss = 4 / (a² + b²).
                    hww[(l, l)] += 4.0 / (a * a + b * b);
                    rw[l] += -gwl + hws * gp / hd;
                    l1_terms.push((l, gp, hws, hd));
                }
            }
        }
        let z = &self.space.z;
        let hz = &hww * z;
        let with_s = matches!(self.mode, Mode::Condition | Mode::Gap { .. });
        let ny = if with_s { m + 1 } else { m };
        let mut h = DMatrix::zeros(ny, ny);
        h.view_mut((0, 0), (m, m)).copy_from(&(z.transpose() * &hz));
        let mut rhs = DVector::zeros(ny);
        rhs.rows_mut(0, m).copy_from(&(z.transpose() * &rw));
        let mut grad_s = 0.0;
        if with_s {
            // s enters the lower LMI as −s I.
            let hws = DVector::from_iterator(nl, (0..nl).map(|l| -wu_lo.column(l).norm_squared()));
            let hcs = z.transpose() * hws;
            h.view_mut((0, m), (m, 1)).copy_from(&hcs);
            h.view_mut((m, 0), (1, m)).copy_from(&hcs.transpose());
            grad_s = lo.w.trace() - tau;
            let mut hss = lo.w.norm_squared();
            if let Mode::Gap { lambda_bar, .. } = self.mode {
                let d = lambda_bar - s;
                grad_s += 1.0 / d;
                hss += 1.0 / (d * d);
            }
            h[(m, m)] = hss;
            rhs[m] = -grad_s;
        }
        let dy = solve_spd(h, &rhs)?;
        let mut dx = DVector::zeros(self.dim());
        dx.rows_mut(0, ny).copy_from(&dy);
        // Decrement² = −gᵀ dx over all variables.
        let gc = z.transpose() * &gw;
        let mut dec2 = -gc.dot(&dy.rows(0, m));
        if with_s {
            dec2 -= grad_s * dy[m];
        }
        if !l1_terms.is_empty() {
            let dw = z * dy.rows(0, m);
            for (k, &(l, gp, hws, hd)) in l1_terms.iter().enumerate() {
                let dp = (-gp - hws * dw[l]) / hd;
                dx[m + k] = dp;
                dec2 -= gp * dp;
            }
        }
        Ok((dx, dec2))
    }
}

/// Solves `H y = r` for symmetric positive definite `H`, with one retry under a tiny diagonal
/// shift (1e-12 of the largest diagonal entry: below the accuracy we ask of a Newton step).
fn solve_spd(h: DMatrix<f64>, r: &DVector<f64>) -> Result<DVector<f64>, SolverStatus> {
    let n = h.nrows();
    let dmax = h.diagonal().amax().max(f64::MIN_POSITIVE);
    if let Some(ch) = Cholesky::new(h.clone()) {
        return Ok(ch.solve(r));
    }
    let shifted = h + DMatrix::<f64>::identity(n, n) * (1e-12 * dmax);
    Cholesky::new(shifted)
        .map(|ch| ch.solve(r))
        .ok_or(SolverStatus::NumericalBreakdown)
}

/// Runs the barrier method from the strictly feasible `x0` until `stop(x, gap)` holds or
/// `max_newton` Newton steps have been taken.
///
/// Returns the last iterate (strictly feasible, so a valid design) also when the method stops
/// without meeting `stop` (the step budget, a line search that can make no progress above the
/// round-off floor, a breakdown); the caller judges it by its bound. `None` if `x0` is not
/// strictly feasible.
pub(crate) fn solve(
    problem: &Problem<'_>,
    x0: DVector<f64>,
    max_newton: usize,
    stop: impl Fn(&DVector<f64>, f64) -> bool,
) -> Option<Outcome> {
    const MU: f64 = 10.0;
    // Centring is stopped at decrement²/2 ≤ 1e-7: the iterate is then close enough to the
    // central path that ν/τ bounds the gap up to a factor ≈ 1 (Boyd & Vandenberghe §11.3.3).
    const NEWTON_TOL: f64 = 1e-7;
    let nu = problem.nu();
    let mut x = x0;
    let mut phi = problem.barrier(&x)?;
    let mut tau = nu / problem.objective(&x).abs().max(1e-3);
    let mut steps = 0;
    // The gap bound ν/τ is valid at the *centred* iterates only; the lower bound keeps the best.
    let mut lower_bound = f64::NEG_INFINITY;
    let out = |x: DVector<f64>, steps, lower_bound| {
        Some(Outcome {
            x,
            newton_steps: steps,
            lower_bound,
        })
    };
    loop {
        let mut prev_dec2 = f64::INFINITY;
        loop {
            if steps >= max_newton {
                // The step budget is spent.
                return out(x, steps, lower_bound);
            }
            let (dx, dec2) = match problem.newton(&x, tau) {
                Ok(v) => v,
                // Numerical breakdown of the Newton system.
                Err(_) => return out(x, steps, lower_bound),
            };
            steps += 1;
            if dec2 / 2.0 <= NEWTON_TOL {
                break;
            }
            // Stagnation at the round-off floor: near the end the Newton matrix has entries up to
            // 1/a² for slacks a ≈ 1e-9, and steps stop reducing a small decrement. The point is
            // then as central as double precision allows.
            if dec2 < 1e-3 && dec2 > 0.5 * prev_dec2 {
                break;
            }
            prev_dec2 = dec2;
            let fdx = problem.objective(&dx);
            let mut t = 1.0;
            let mut accepted = false;
            while t > 1e-14 {
                let xn = &x + &dx * t;
                if let Some(phin) = problem.barrier(&xn) {
                    // The decrease is computed as a difference of small terms so that it stays
                    // accurate when τ fᵀx is large.
                    let decrease = tau * t * fdx + (phin - phi);
                    if decrease <= -0.25 * t * dec2 {
                        x = xn;
                        phi = phin;
                        accepted = true;
                        break;
                    }
                }
                t *= 0.5;
            }
            if !accepted {
                if dec2 < 1e-4 {
                    // Round-off floor: the point is centred as well as double precision allows.
                    break;
                }
                // The line search can make no progress above the round-off floor.
                return out(x, steps, lower_bound);
            }
        }
        let gap = nu / tau;
        lower_bound = lower_bound.max(problem.objective(&x) - gap);
        if stop(&x, gap) {
            return out(x, steps, lower_bound);
        }
        tau *= MU;
        // The barrier value at x changes with τ only through the objective term, which is
        // evaluated separately; φ stays valid.
    }
}
