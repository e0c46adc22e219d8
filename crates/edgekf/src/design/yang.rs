//! The Yang et al. (2019) construction of a universally rigid framework: it designs the graph and
//! the stress together, in closed form.
//!
//! Order the agents: the leaders first (or agents `0..=D` when there are none), then repeatedly
//! the nearest not yet ordered agent to the last one ordered (a greedy spatial path). In that
//! order let `P̄ = [Pᵀ; 1ᵀ]` ((D + 1) × N). For each
//! `k = 0, …, N − D − 2` take the `D + 2` consecutive agents `k, …, k + D + 1`; their columns of
//! `P̄` have (for a generic configuration) a one-dimensional null space, spanned by `d_k`.
//! Padding `d_k` with zeros gives column `k` of `D` (N × (N − D − 1)), and `Ω = D Dᵀ` is the
//! stress:
//! - `Ω [P 1] = D (Dᵀ [P 1]) = 0` — every column is its own null vector (one null vector of the
//!   whole stacked system would leave many columns ≈ 0 and `Ω` rank-deficient);
//! - `Ω ⪰ 0` by construction;
//! - `D` is banded with its first nonzero of column `k` in row `k`, so it has full column rank
//!   `N − D − 1` whenever `d_k` starts with a nonzero (generic), hence `rank Ω = N − D − 1`.
//!
//! `Ω_ij ≠ 0` only for agents at most `D + 1` apart in the order: each agent links to its
//! `D + 1` predecessors, a D-trilateration graph with a banded Laplacian (in that order). The
//! ordering is ours (Yang et al. take the agents as numbered): consecutive groups of random
//! agents far apart give long links and a badly conditioned `Ω` (we measured `λ_max/λ_min`
//! ≈ 4e5 for 50 random agents in index order), a spatial path keeps the groups local. The candidate links are ignored. The result
//! is scaled to smallest nonzero eigenvalue 1.
//!
//! # References
//! Q. Yang, Z. Sun, M. Cao, H. Fang, J. Chen, "Constructing universally rigid tensegrity
//! frameworks with application in multiagent formation control", IEEE TAC 64(1), 2019.

use nalgebra::DMatrix;

use super::{
    complement_basis, finish, validate, Candidate, Design, DesignError, Finish, StressSpace,
};

/// Designs graph and weights by the Yang 2019 construction (see the module docs).
///
/// # Errors
/// [`DesignError::NonGeneric`] when some `D + 2` consecutive agents lie in a common affine
/// hyperplane (their null space is not one-dimensional) or a null vector starts with zero
/// (the rank would drop).
///
/// ```
/// use edgekf::design::{generators, yang};
/// let d = yang::design(&generators::hexagon_candidate()).unwrap();
/// assert_eq!(d.framework.graph().links().len(), 3 + 3 * 7); // band of width D + 1 = 3
/// ```
pub fn design(candidate: &Candidate) -> Result<Design, DesignError> {
    let flat = validate(candidate)?;
    let dim = candidate.dim;
    let n = candidate.config.len();
    let cols = n - dim - 1;
    let order = greedy_order(&flat, dim, n, &candidate.leaders);
    let mut d = DMatrix::zeros(n, cols);
    for k in 0..cols {
        let group = &order[k..k + dim + 2];
        let Some(v) = group_null(&flat, dim, group) else {
            return Err(DesignError::NonGeneric(format!(
                "agents {group:?} lie in a common affine hyperplane (Yang construction needs every \
                 D + 2 consecutive agents to span R^D)"
            )));
        };
        let vmax = v.amax();
        // 1e-9 relative: an entry this small is a zero of a non-generic configuration, not
        // round-off (the SVD null vector is accurate to ≈ 1e-15).
        if v[0].abs() <= 1e-9 * vmax {
            return Err(DesignError::NonGeneric(format!(
                "agent {} is affinely dependent on agents {:?} (the null vector of their group \
                 starts with zero, so rank Ω < N − D − 1)",
                order[k],
                &order[k + 1..k + dim + 2]
            )));
        }
        for r in 0..dim + 2 {
            d[(order[k + r], k)] = v[r];
        }
    }
    let omega = &d * d.transpose();
    let scale = omega.amax();
    let mut links = Vec::new();
    let mut w = Vec::new();
    for a in 0..n {
        for b in a + 1..(a + dim + 2).min(n) {
            let (i, j) = (order[a].min(order[b]), order[a].max(order[b]));
            // Entries at 1e-13 of the largest are round-off of an exact zero.
            if omega[(i, j)].abs() > 1e-13 * scale {
                links.push((i, j));
                w.push(-omega[(i, j)]);
            }
        }
    }
    crate::graph::Graph::new(n, &links)?;
    let space = StressSpace::new(&flat, dim, &links)?;
    finish(
        candidate,
        &links,
        &w,
        &space,
        Finish {
            drop_rel: 0.0,
            normalise: true,
            method: "yang",
            newton_steps: 0,
            solver: "construction",
            gap: 0.0,
        },
    )
}

/// Null vector of `[Pᵀ; 1ᵀ]` restricted to `group` (D + 2 agents), or `None` if degenerate.
fn group_null(flat: &[f64], dim: usize, group: &[usize]) -> Option<nalgebra::DVector<f64>> {
    let mut a = DMatrix::zeros(dim + 2, dim + 1);
    for (r, &g) in group.iter().enumerate() {
        a[(r, 0)] = 1.0;
        for c in 0..dim {
            a[(r, c + 1)] = flat[g * dim + c];
        }
    }
    let (null, rank) = complement_basis(&a);
    (rank == dim + 1 && null.ncols() == 1).then(|| null.column(0).into_owned())
}

/// Leaders (or `0..=D`) first; then, to close group `k` = `order[k..=k+D]` plus one more agent,
/// the unordered agent that makes the group's null vector put the largest share
/// `|d_k[0]| / ‖d_k‖` on its first agent `order[k]` — the pivot of column k of the banded `D`.
/// Large pivots keep `D` (and so `Ω`) well conditioned; small ones compound along the band.
fn greedy_order(flat: &[f64], dim: usize, n: usize, leaders: &[usize]) -> Vec<usize> {
    let mut order: Vec<usize> = if leaders.is_empty() {
        (0..=dim).collect()
    } else {
        leaders.to_vec()
    };
    let mut used = vec![false; n];
    for &a in &order {
        used[a] = true;
    }
    let mut group = Vec::with_capacity(dim + 2);
    while order.len() < n {
        let k = order.len() - dim - 1;
        let mut best = None;
        let mut best_score = -1.0;
        for b in (0..n).filter(|&b| !used[b]) {
            group.clear();
            group.extend_from_slice(&order[k..]);
            group.push(b);
            let score = group_null(flat, dim, &group).map_or(0.0, |v| v[0].abs() / v.norm());
            if score > best_score {
                best_score = score;
                best = Some(b);
            }
        }
        let next = best.expect("an agent is left");
        used[next] = true;
        order.push(next);
    }
    order
}
