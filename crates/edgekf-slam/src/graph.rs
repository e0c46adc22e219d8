//! Graph Laplacians of §2.1: checks and connectivity.
//!
//! A Laplacian is `𝓛 = 𝓓 − 𝓦` with non-negative weights `w_ij = −l_ij` (i ≠ j) and zero row sums. A directed
//! edge `(i, j)` (`l_ij < 0`) means that agent `i` receives information from (measures) agent `j`.

use nalgebra::DMatrix;

/// Why a matrix is not a graph Laplacian.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LaplacianDefect {
    /// The matrix is not `n × n`.
    #[error("it is {rows} × {cols}, expected {n} × {n}")]
    Shape {
        /// Rows found.
        rows: usize,
        /// Columns found (of the first short or long row, or of every row).
        cols: usize,
        /// Expected size.
        n: usize,
    },
    /// An entry is NaN or infinite.
    #[error("entry ({row}, {col}) is not finite")]
    NotFinite {
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
    },
    /// An off-diagonal entry is positive, i.e. a negative edge weight.
    #[error("off-diagonal entry ({row}, {col}) = {value} is positive (edge weights must be non-negative)")]
    PositiveOffDiagonal {
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// The entry.
        value: f64,
    },
    /// A row does not sum to zero.
    #[error("row {row} sums to {sum}, not 0")]
    RowSum {
        /// Row (0-based).
        row: usize,
        /// The row sum.
        sum: f64,
    },
    /// An undirected graph's Laplacian is not symmetric.
    #[error("entry ({row}, {col}) = {a} differs from entry ({col}, {row}) = {b} (an undirected graph needs a symmetric Laplacian)")]
    NotSymmetric {
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// `l[row][col]`.
        a: f64,
        /// `l[col][row]`.
        b: f64,
    },
}

/// Tolerance on row sums and symmetry, relative to the largest entry.
const REL_TOL: f64 = 1e-12;

/// Builds an `n × n` matrix from nested rows, checking the shape.
///
/// # Errors
/// [`LaplacianDefect::Shape`] when there are not `n` rows of `n` entries.
pub fn matrix_from_rows(rows: &[Vec<f64>], n: usize) -> Result<DMatrix<f64>, LaplacianDefect> {
    if rows.len() != n {
        let cols = rows.first().map_or(0, Vec::len);
        return Err(LaplacianDefect::Shape {
            rows: rows.len(),
            cols,
            n,
        });
    }
    if let Some(bad) = rows.iter().find(|r| r.len() != n) {
        return Err(LaplacianDefect::Shape {
            rows: rows.len(),
            cols: bad.len(),
            n,
        });
    }
    Ok(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
}

/// Checks that `l` is the Laplacian of a weighted graph (§2.1): finite, non-positive off-diagonal entries, zero
/// row sums, and symmetric when `undirected`.
///
/// # Errors
/// The first [`LaplacianDefect`] found.
pub fn check_laplacian(l: &DMatrix<f64>, undirected: bool) -> Result<(), LaplacianDefect> {
    let n = l.nrows();
    if l.ncols() != n {
        return Err(LaplacianDefect::Shape {
            rows: n,
            cols: l.ncols(),
            n,
        });
    }
    let scale = l.iter().fold(1.0_f64, |acc, v| acc.max(v.abs()));
    let tol = REL_TOL * scale * n.max(1) as f64;
    for i in 0..n {
        for j in 0..n {
            if !l[(i, j)].is_finite() {
                return Err(LaplacianDefect::NotFinite { row: i, col: j });
            }
        }
    }
    for i in 0..n {
        for j in 0..n {
            if i != j && l[(i, j)] > 0.0 {
                return Err(LaplacianDefect::PositiveOffDiagonal {
                    row: i,
                    col: j,
                    value: l[(i, j)],
                });
            }
        }
        let sum: f64 = l.row(i).iter().sum();
        if sum.abs() > tol {
            return Err(LaplacianDefect::RowSum { row: i, sum });
        }
    }
    if undirected {
        for i in 0..n {
            for j in (i + 1)..n {
                if (l[(i, j)] - l[(j, i)]).abs() > tol {
                    return Err(LaplacianDefect::NotSymmetric {
                        row: i,
                        col: j,
                        a: l[(i, j)],
                        b: l[(j, i)],
                    });
                }
            }
        }
    }
    Ok(())
}

/// The vertices reachable from `start` following edges `i → j` with `l_ij < 0` (or the reversed edges).
fn reachable(l: &DMatrix<f64>, start: usize, reversed: bool) -> Vec<bool> {
    let n = l.nrows();
    let mut seen = vec![false; n];
    let mut stack = vec![start];
    seen[start] = true;
    while let Some(i) = stack.pop() {
        for j in 0..n {
            let w = if reversed { l[(j, i)] } else { l[(i, j)] };
            if j != i && w < 0.0 && !seen[j] {
                seen[j] = true;
                stack.push(j);
            }
        }
    }
    seen
}

/// Whether the directed graph of the Laplacian `l` is strongly connected (Assumption 1 for G⁺).
pub fn is_strongly_connected(l: &DMatrix<f64>) -> bool {
    let n = l.nrows();
    n == 0
        || (reachable(l, 0, false).iter().all(|&s| s) && reachable(l, 0, true).iter().all(|&s| s))
}

/// Whether the undirected graph of the symmetric Laplacian `l` is connected (Assumptions 1 and 4).
pub fn is_connected(l: &DMatrix<f64>) -> bool {
    l.nrows() == 0 || reachable(l, 0, false).iter().all(|&s| s)
}

/// The in-neighbours `j` of `i` (edges `(i, j)`, `l_ij < 0`) in increasing order, with weights `a_ij = −l_ij`.
pub fn neighbours(l: &DMatrix<f64>, i: usize) -> Vec<(usize, f64)> {
    (0..l.ncols())
        .filter(|&j| j != i && l[(i, j)] < 0.0)
        .map(|j| (j, -l[(i, j)]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(rows: &[&[f64]]) -> DMatrix<f64> {
        let v: Vec<Vec<f64>> = rows.iter().map(|r| r.to_vec()).collect();
        matrix_from_rows(&v, v.len()).unwrap()
    }

    #[test]
    fn cycle_is_strongly_connected_path_is_not() {
        let cycle = m(&[&[1.0, -1.0, 0.0], &[0.0, 1.0, -1.0], &[-1.0, 0.0, 1.0]]);
        assert!(check_laplacian(&cycle, false).is_ok());
        assert!(is_strongly_connected(&cycle));
        assert!(matches!(
            check_laplacian(&cycle, true),
            Err(LaplacianDefect::NotSymmetric { .. })
        ));
        let path = m(&[&[1.0, -1.0, 0.0], &[0.0, 1.0, -1.0], &[0.0, 0.0, 0.0]]);
        assert!(!is_strongly_connected(&path));
    }

    #[test]
    fn defects_are_named() {
        let bad = m(&[&[1.0, -2.0], &[-1.0, 1.0]]);
        let e = check_laplacian(&bad, false).unwrap_err();
        assert_eq!(e.to_string(), "row 0 sums to -1, not 0");
        let pos = m(&[&[-1.0, 1.0], &[1.0, -1.0]]);
        let e = check_laplacian(&pos, true).unwrap_err();
        assert!(
            e.to_string()
                .contains("off-diagonal entry (0, 1) = 1 is positive"),
            "{e}"
        );
        let e = matrix_from_rows(&[vec![1.0, -1.0]], 2).unwrap_err();
        assert_eq!(e.to_string(), "it is 1 × 2, expected 2 × 2");
    }

    #[test]
    fn disconnected_undirected() {
        let l = m(&[&[1.0, -1.0, 0.0], &[-1.0, 1.0, 0.0], &[0.0, 0.0, 0.0]]);
        assert!(check_laplacian(&l, true).is_ok());
        assert!(!is_connected(&l));
        assert_eq!(neighbours(&l, 0), vec![(1, 1.0)]);
    }
}
