//! The stress SDPs in Clarabel's conic form (feature `clarabel`).
//!
//! Clarabel solves `min ½ xᵀP x + qᵀx` s.t. `A x + s = b`, `s ∈ K`. We pass the three problems
//! of the tailored interior-point method ([`super::ipm::Mode`]), always with the weights'
//! coordinates `c` first (so `w = Z c` reads them back):
//!
//! - `Condition`: `x = (c, t)`, `min t` s.t. `M(c) − I ⪰ 0`, `t I − M(c) ⪰ 0`. This is the
//!   IPM's `max s` s.t. `s I ⪯ M ⪯ I` under the change of scale `c ↦ c / s`, `t = 1/s` (both
//!   give the best ratio `κ* = λ_max / λ_min`). We give Clarabel this form because its
//!   objective `t = κ* ≥ 1` makes Clarabel's relative duality gap (gap over
//!   `max(1, |objective|)`) a relative accuracy of `κ*`; with `−s`, `|s| < 1`, the same
//!   tolerance would be absolute on `s` and stalled short of it on the hexagon (measured:
//!   `AlmostSolved` at gap 4.7e-8 on `s` = 0.0194). A flexible framework makes this form
//!   infeasible, which Clarabel certifies (`PrimalInfeasible`);
//! - `Gap`: `x = (c, s)`, `min −s` s.t. `M(c) − s I ⪰ 0`, `λ̄ − s ≥ 0`, `w̄ ∓ (Z c)_l ≥ 0`;
//! - `L1`: `x = (c, p)`, `min Σ p` s.t. `M(c) − I ⪰ 0`, `κ̄ I − M(c) ⪰ 0`, `p_k ∓ (Z c)_l ≥ 0`,
//!
//! with `M(c) = Q L(Z c) Qᵀ = Σ_k c_k A_k`, `A_k = U diag(Z e_k) Uᵀ` (see [`super::StressSpace`]).
//! The weights are parametrised over the equilibrium stresses, so no (linearly dependent)
//! equality rows `L [P 1] = 0` reach the solver.
//!
//! An LMI `F(x) = F₀ + Σ x_j F_j ⪰ 0` becomes the slack `s = svec(F(x)) = b − A x` in
//! `PSDTriangleConeT(n')`, i.e. `b = svec(F₀)` and column `j` of `A` is `−svec(F_j)`.
//! Clarabel's `svec` stacks the **upper triangle column by column**,
//! `(X₀₀, √2 X₀₁, X₁₁, √2 X₀₂, √2 X₁₂, X₂₂, …)`, with the off-diagonal entries scaled by `√2`
//! so that `svec(X)ᵀ svec(Y) = tr(X Y)` (Clarabel's documentation of `PSDTriangleConeT` and its
//! SDP example).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, SolverStatus as ClStatus, SupportedConeT,
};
use nalgebra::{DMatrix, DVector};

use super::Mode;
use super::{DesignError, SolverStatus, StressSpace};

/// Result of a Clarabel solve.
pub(crate) struct Outcome {
    /// Primal solution `x` (`(c, t)`, `(c, s)` or `(c, p)`, see the module docs).
    pub x: DVector<f64>,
    /// Clarabel iterations.
    pub iterations: usize,
    /// `|primal − dual objective|` at the solution.
    pub gap: f64,
}

/// `svec` of a symmetric `n × n` matrix in Clarabel's order (upper triangle by columns, off
/// diagonal scaled by √2).
fn svec_index(n: usize) -> Vec<(usize, usize)> {
    let mut idx = Vec::with_capacity(n * (n + 1) / 2);
    for j in 0..n {
        for i in 0..=j {
            idx.push((i, j));
        }
    }
    idx
}

/// `svec(A_k)` for every stress basis vector: an `n'(n'+1)/2 × m` matrix.
fn svec_basis(space: &StressSpace) -> (DMatrix<f64>, Vec<(usize, usize)>) {
    let u = &space.u();
    let np = u.nrows();
    let idx = svec_index(np);
    let sqrt2 = std::f64::consts::SQRT_2;
    // svec(u_l u_lᵀ) per link, then combine with Z.
    let per_link = DMatrix::from_fn(idx.len(), u.ncols(), |r, l| {
        let (i, j) = idx[r];
        let v = u[(i, l)] * u[(j, l)];
        if i == j {
            v
        } else {
            sqrt2 * v
        }
    });
    (per_link * &space.z, idx)
}

/// Dense → CSC, dropping exact zeros.
fn to_csc(a: &DMatrix<f64>) -> CscMatrix<f64> {
    let (m, n) = a.shape();
    let mut colptr = Vec::with_capacity(n + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for j in 0..n {
        for i in 0..m {
            let v = a[(i, j)];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

/// A stable name for Clarabel's status (for [`SolverStatus::Clarabel`]).
fn status_name(s: ClStatus) -> &'static str {
    match s {
        ClStatus::Unsolved => "Unsolved",
        ClStatus::Solved => "Solved",
        ClStatus::PrimalInfeasible => "PrimalInfeasible",
        ClStatus::DualInfeasible => "DualInfeasible",
        ClStatus::AlmostSolved => "AlmostSolved",
        ClStatus::AlmostPrimalInfeasible => "AlmostPrimalInfeasible",
        ClStatus::AlmostDualInfeasible => "AlmostDualInfeasible",
        ClStatus::MaxIterations => "MaxIterations",
        ClStatus::MaxTime => "MaxTime",
        ClStatus::NumericalError => "NumericalError",
        ClStatus::InsufficientProgress => "InsufficientProgress",
        ClStatus::CallbackTerminated => "CallbackTerminated",
    }
}

/// Solves `mode` on `space` with Clarabel. `tol_gap` is passed as both Clarabel's absolute and
/// relative duality-gap tolerance (Clarabel divides the gap by `max(1, |objective|)`).
///
/// # Errors
/// [`DesignError::NotUniversallyRigid`] when Clarabel certifies the `Condition` form infeasible;
/// otherwise [`DesignError::Solver`] with [`SolverStatus::Clarabel`] naming Clarabel's status
/// unless it is `Solved`.
pub(crate) fn solve(
    space: &StressSpace,
    mode: &Mode,
    tol_gap: f64,
) -> Result<Outcome, DesignError> {
    let (q, a, b, cones) = program(space, mode);
    let settings = DefaultSettings::<f64> {
        verbose: false,
        tol_gap_abs: tol_gap,
        tol_gap_rel: tol_gap,
        // faer's supernodal LDL: the KKT system holds two dense n'(n'+1)/2 blocks (1128 for
        // 50 agents in 2-D); measured 38 s for the 50-agent SDP in release.
        direct_solve_method: "faer".into(),
        ..DefaultSettings::default()
    };
    let p = CscMatrix::zeros((q.len(), q.len()));
    let fail = |status: &'static str, iterations: usize| DesignError::Solver {
        status: SolverStatus::Clarabel(status),
        iterations,
    };
    let mut solver = DefaultSolver::new(&p, &q, &to_csc(&a), &b, &cones, settings)
        .map_err(|_| fail("setup error", 0))?;
    solver.solve();
    let sol = &solver.solution;
    let iterations = sol.iterations as usize;
    match sol.status {
        ClStatus::Solved => {}
        ClStatus::PrimalInfeasible if matches!(mode, Mode::Condition) => {
            let np = space.np();
            return Err(DesignError::NotUniversallyRigid(format!(
                "no positive semidefinite stress of rank N − D − 1 = {np} exists on this graph \
                 (Clarabel certifies that no stress has Q L Qᵀ ⪰ I)"
            )));
        }
        other => return Err(fail(status_name(other), iterations)),
    }
    Ok(Outcome {
        x: DVector::from_column_slice(&sol.x),
        iterations,
        gap: (sol.obj_val - sol.obj_val_dual).abs(),
    })
}

/// A row block of Clarabel's `b − A x ∈ K` and its cone.
type Block = (DMatrix<f64>, DVector<f64>, SupportedConeT<f64>);

/// `mode` on `space` as Clarabel's conic program: the objective `q`, the stacked `A` and `b`,
/// and the cones of their row blocks (the LMIs, then the linear inequalities).
fn program(
    space: &StressSpace,
    mode: &Mode,
) -> (Vec<f64>, DMatrix<f64>, Vec<f64>, Vec<SupportedConeT<f64>>) {
    let m = space.z.ncols();
    let nl = space.z.nrows();
    let penalised: Vec<usize> = match mode {
        Mode::L1 { penalised, .. } => (0..nl).filter(|&l| penalised[l]).collect(),
        _ => Vec::new(),
    };
    let nx = match mode {
        Mode::Condition | Mode::Gap { .. } => m + 1,
        Mode::L1 { .. } => m + penalised.len(),
    };
    let mut q = vec![0.0; nx];
    let mut blocks = lmi_blocks(space, mode, &mut q);
    blocks.extend(linear_block(space, mode, &penalised, &mut q));
    let rows: usize = blocks.iter().map(|(a, _, _)| a.nrows()).sum();
    let mut a = DMatrix::zeros(rows, nx);
    let mut b = Vec::with_capacity(rows);
    let mut cones = Vec::with_capacity(blocks.len());
    let mut r0 = 0;
    for (ab, bb, cone) in blocks {
        a.view_mut((r0, 0), ab.shape()).copy_from(&ab);
        b.extend(bb.iter().copied());
        r0 += ab.nrows();
        cones.push(cone);
    }
    (q, a, b, cones)
}

/// The LMI blocks, filling their part of the objective `q` (of length `nx`): the lower
/// `M(c) − s I ⪰ 0` (Gap) or `M(c) − I ⪰ 0`, as `b − A x = svec(M(c)) − s svec(I)`; the upper
/// `t I − M(c) ⪰ 0` (Condition) or `κ̄ I − M(c) ⪰ 0` (L1).
fn lmi_blocks(space: &StressSpace, mode: &Mode, q: &mut [f64]) -> Vec<Block> {
    let (m, nx, np) = (space.z.ncols(), q.len(), space.np());
    let (svec_a, idx) = svec_basis(space);
    let nvec = idx.len();
    let svec_i = DVector::from_iterator(nvec, idx.iter().map(|&(i, j)| f64::from(i == j)));
    let psd = || SupportedConeT::PSDTriangleConeT(np);
    let mut a_lo = DMatrix::zeros(nvec, nx);
    a_lo.columns_mut(0, m).copy_from(&(-&svec_a));
    let b_lo = match mode {
        Mode::Gap { .. } => {
            a_lo.column_mut(m).copy_from(&svec_i);
            q[m] = -1.0;
            DVector::zeros(nvec)
        }
        Mode::Condition | Mode::L1 { .. } => -&svec_i,
    };
    let mut blocks = vec![(a_lo, b_lo, psd())];
    let mut a_up = DMatrix::zeros(nvec, nx);
    a_up.columns_mut(0, m).copy_from(&svec_a);
    match mode {
        Mode::Condition => {
            a_up.column_mut(m).copy_from(&(-&svec_i));
            q[m] = 1.0;
            blocks.push((a_up, DVector::zeros(nvec), psd()));
        }
        Mode::L1 { kappa, .. } => blocks.push((a_up, &svec_i * *kappa, psd())),
        Mode::Gap { .. } => {}
    }
    blocks
}

/// The linear inequalities, filling their part of the objective: for Gap `λ̄ − s ≥ 0`,
/// `w̄ ∓ (Z c)_l ≥ 0`; for L1 `p_k ∓ (Z c)_l ≥ 0` over the `penalised` links, objective `Σ p`.
fn linear_block(
    space: &StressSpace,
    mode: &Mode,
    penalised: &[usize],
    q: &mut [f64],
) -> Option<Block> {
    let (z, m, nl, nx) = (&space.z, space.z.ncols(), space.z.nrows(), q.len());
    match mode {
        Mode::Condition => None,
        Mode::Gap { lambda_bar, wmax } => {
            let mut a = DMatrix::zeros(1 + 2 * nl, nx);
            let mut b = DVector::from_element(1 + 2 * nl, *wmax);
            a[(0, m)] = 1.0;
            b[0] = *lambda_bar;
            a.view_mut((1, 0), (nl, m)).copy_from(z);
            a.view_mut((1 + nl, 0), (nl, m)).copy_from(&(-z));
            Some((a, b, SupportedConeT::NonnegativeConeT(1 + 2 * nl)))
        }
        Mode::L1 { .. } => {
            let np_ = penalised.len();
            let mut a = DMatrix::zeros(2 * np_, nx);
            for (k, &l) in penalised.iter().enumerate() {
                q[m + k] = 1.0;
                a.view_mut((k, 0), (1, m)).copy_from(&z.row(l));
                a.view_mut((np_ + k, 0), (1, m)).copy_from(&(-z.row(l)));
                a[(k, m + k)] = -1.0;
                a[(np_ + k, m + k)] = -1.0;
            }
            let zeros = DVector::zeros(2 * np_);
            Some((a, zeros, SupportedConeT::NonnegativeConeT(2 * np_)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svec_is_an_isometry_in_clarabel_order() {
        // tr(X Y) = svec(X)ᵀ svec(Y) for symmetric X, Y.
        let x = DMatrix::from_row_slice(3, 3, &[1.0, 2.0, 3.0, 2.0, 4.0, 5.0, 3.0, 5.0, 6.0]);
        let y = DMatrix::from_row_slice(3, 3, &[0.5, -1.0, 0.0, -1.0, 2.0, 1.5, 0.0, 1.5, -3.0]);
        let idx = svec_index(3);
        assert_eq!(idx[..4], [(0, 0), (0, 1), (1, 1), (0, 2)]);
        let sv = |a: &DMatrix<f64>| -> Vec<f64> {
            idx.iter()
                .map(|&(i, j)| {
                    if i == j {
                        a[(i, j)]
                    } else {
                        std::f64::consts::SQRT_2 * a[(i, j)]
                    }
                })
                .collect()
        };
        let dot: f64 = sv(&x).iter().zip(sv(&y)).map(|(a, b)| a * b).sum();
        assert!((dot - (&x * &y).trace()).abs() < 1e-12);
    }
}
