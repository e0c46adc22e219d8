//! Performance metrics (names fixed by DESIGN.md).

use nalgebra::SMatrix;

/// The metrics every run reports, in output order.
pub const METRICS: [&str; 4] = ["est_error", "est_error_sq", "cov_trace", "procrustes"];

/// Procrustes error of positions `z` against the configuration `p` (thesis Def. 2.9):
/// `min_{t, Ω ᵀΩ = I} ‖Z Ω + 1 tᵀ − P‖_F / N`, solved by centring both and the SVD of `Z_cᵀ P_c`
/// (orthogonal Procrustes; reflections allowed, as `Ωᵀ Ω = I` allows them).
///
/// `z(i, d)` returns coordinate `d` of agent `i`; `p` is agent-major.
pub fn procrustes<const D: usize>(n: usize, z: impl Fn(usize, usize) -> f64, p: &[f64]) -> f64 {
    let mut zc = [0.0; D];
    let mut pc = [0.0; D];
    for i in 0..n {
        for d in 0..D {
            zc[d] += z(i, d) / n as f64;
            pc[d] += p[i * D + d] / n as f64;
        }
    }
    let mut m = SMatrix::<f64, D, D>::zeros();
    for i in 0..n {
        for a in 0..D {
            for b in 0..D {
                m[(a, b)] += (z(i, a) - zc[a]) * (p[i * D + b] - pc[b]);
            }
        }
    }
    let omega = orthogonal_factor(&m);
    let mut ss = 0.0;
    for i in 0..n {
        for b in 0..D {
            let mut v = -(p[i * D + b] - pc[b]);
            for a in 0..D {
                v += (z(i, a) - zc[a]) * omega[(a, b)];
            }
            ss += v * v;
        }
    }
    ss.sqrt() / n as f64
}

/// `U Vᵀ` from the SVD `M = U Σ Vᵀ`: the orthogonal matrix nearest to `M` (stack only).
fn orthogonal_factor<const D: usize>(m: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    match D {
        1 => SMatrix::from_fn(|_, _| if m[(0, 0)] < 0.0 { -1.0 } else { 1.0 }),
        2 => {
            let svd = nalgebra::Matrix2::from_fn(|i, j| m[(i, j)]).svd(true, true);
            let o = svd.u.expect("u computed") * svd.v_t.expect("v computed");
            SMatrix::from_fn(|i, j| o[(i, j)])
        }
        3 => {
            let svd = nalgebra::Matrix3::from_fn(|i, j| m[(i, j)]).svd(true, true);
            let o = svd.u.expect("u computed") * svd.v_t.expect("v computed");
            SMatrix::from_fn(|i, j| o[(i, j)])
        }
        _ => unreachable!("dimensions are 1, 2 or 3"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn procrustes_ignores_rigid_motions_and_sees_shape_changes() {
        let p = [0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0, 1.0];
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let moved: Vec<f64> = (0..4)
            .flat_map(|i| {
                [
                    c * p[2 * i] - s * p[2 * i + 1] + 5.0,
                    s * p[2 * i] + c * p[2 * i + 1] - 1.0,
                ]
            })
            .collect();
        assert!(procrustes::<2>(4, |i, d| moved[2 * i + d], &p) < 1e-14);
        let mirrored: Vec<f64> = (0..4).flat_map(|i| [-p[2 * i], p[2 * i + 1]]).collect();
        assert!(procrustes::<2>(4, |i, d| mirrored[2 * i + d], &p) < 1e-14);
        let mut bent = p;
        bent[7] += 0.4;
        let e = procrustes::<2>(4, |i, d| bent[2 * i + d], &p);
        assert!(e > 0.01 && e < 0.4 / 4.0 + 1e-12, "{e}");
    }
}
