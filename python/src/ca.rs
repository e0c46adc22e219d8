//! `EdgeFilter(kind="rkf-ca")`: B constant-acceleration edge filters with intermittent
//! observations (Li & Rajan eqs. 5–7; the `rkf-ca` estimator of the engine), over the library's
//! batched [`CaBatch`] (edges in place of Monte Carlo runs).

use edgekf::estimate::ca::{packed_index, packed_len, CaBatch, CaModel};
use nalgebra::DMatrix;
use numpy::{PyArray1, PyArray3, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::flat;

/// The filters and their model, for one dimension D.
struct Bank<const D: usize> {
    batch: CaBatch<D>,
    model: CaModel<D>,
    /// `R` packed by entry, runs innermost (what [`CaBatch::correct_cov`] reads).
    r: Vec<f64>,
    /// Scratch: the observations, `D × B`, runs innermost.
    y: Vec<f64>,
}

enum AnyBank {
    D1(Bank<1>),
    D2(Bank<2>),
    D3(Bank<3>),
}

/// A bank of B CA edge filters of dimension D: state `γ = [z, ż, z̈]` (3 × D per edge).
#[pyclass(module = "edgekf._edgekf", name = "_CaBank", unsendable)]
pub struct CaBank {
    b: usize,
    d: usize,
    bank: AnyBank,
}

fn err(msg: String) -> PyErr {
    PyValueError::new_err(msg)
}

/// Checks a covariance argument (row-major `n × n`, finite entries): symmetric to 1e-12
/// relative, and positive semidefinite (eigenvalues ≥ −1e-12 · max |entry|) or, with
/// `definite`, positive definite (a Cholesky factor exists). The message names `what` (the
/// argument, and the edge of a batch) and says what fails, with the number.
pub(crate) fn check_cov(m: &[f64], n: usize, what: &str, definite: bool) -> PyResult<()> {
    let a = DMatrix::from_row_slice(n, n, m);
    let scale = a.amax();
    for i in 0..n {
        for j in 0..i {
            if (a[(i, j)] - a[(j, i)]).abs() > 1e-12 * scale {
                return Err(err(format!(
                    "{what}: must be symmetric, but entry ({i}, {j}) = {:e} and ({j}, {i}) = {:e}",
                    a[(i, j)],
                    a[(j, i)]
                )));
            }
        }
    }
    let smallest = || {
        a.clone()
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    };
    if definite {
        if a.clone().cholesky().is_none() {
            return Err(err(format!(
                "{what}: must be symmetric positive definite, but its smallest eigenvalue is {:e}",
                smallest()
            )));
        }
    } else {
        let l = smallest();
        if l < -1e-12 * scale {
            return Err(err(format!(
                "{what}: must be symmetric positive semidefinite, but its smallest eigenvalue is {l:e}"
            )));
        }
    }
    Ok(())
}

/// Checks every matrix of a shared (`n × n`) or per-edge (`B × n × n`) covariance argument.
pub(crate) fn check_covs(
    m: &[f64],
    n: usize,
    shared: bool,
    what: &str,
    definite: bool,
) -> PyResult<()> {
    let count = if shared { 1 } else { m.len() / (n * n).max(1) };
    for e in 0..count {
        let name = if shared {
            what.to_string()
        } else {
            format!("{what} of edge {e}")
        };
        check_cov(&m[e * n * n..(e + 1) * n * n], n, &name, definite)?;
    }
    Ok(())
}

impl<const D: usize> Bank<D> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        b: usize,
        dt: f64,
        sigma_w: f64,
        x0: &[f64],
        p0: &[f64],
        p_shared: bool,
        r: &[f64],
        r_shared: bool,
    ) -> PyResult<Self> {
        let n = 3 * D;
        let model = CaModel::<D>::new(dt, sigma_w).map_err(|e| err(e.to_string()))?;
        let first = DMatrix::from_row_slice(n, n, &p0[..n * n]);
        let mut batch =
            CaBatch::<D>::new(b, &first, &vec![0.0; n]).map_err(|e| err(format!("P0: {e}")))?;
        if !p_shared {
            for e in 1..b {
                let m = DMatrix::from_row_slice(n, n, &p0[e * n * n..(e + 1) * n * n]);
                batch.set_covariance(e, &m);
            }
        }
        // Means: γ of edge e at x0[e·3D + a], a = block · D + dimension.
        let mean = batch.mean_mut();
        for e in 0..b {
            for a in 0..n {
                mean[a * b + e] = x0[e * n + a];
            }
        }
        let nr = packed_len(D);
        let mut rp = vec![0.0; nr * b];
        for e in 0..b {
            let m = if r_shared {
                &r[..D * D]
            } else {
                &r[e * D * D..(e + 1) * D * D]
            };
            for i in 0..D {
                for j in i..D {
                    rp[packed_index(D, i, j) * b + e] = m[i * D + j];
                }
            }
        }
        Ok(Self {
            batch,
            model,
            r: rp,
            y: vec![0.0; D * b],
        })
    }

    fn update(&mut self, b: usize, y: &[f64], mask: &[bool]) {
        for e in 0..b {
            for c in 0..D {
                self.y[c * b + e] = y[e * D + c];
            }
        }
        self.batch.correct_cov(&self.r, mask);
        self.batch.correct_mean(&self.y, mask);
    }

    /// `(x̂ as B·3D, P as B·3D·3D)`, row-major per edge.
    fn state(&self, b: usize) -> (Vec<f64>, Vec<f64>) {
        let n = 3 * D;
        let mean = self.batch.mean();
        let mut x = vec![0.0; b * n];
        let mut p = vec![0.0; b * n * n];
        for e in 0..b {
            for a in 0..n {
                x[e * n + a] = mean[a * b + e];
                for c in 0..n {
                    p[(e * n + a) * n + c] = self.batch.cov_entry(packed_index(n, a, c), e);
                }
            }
        }
        (x, p)
    }
}

macro_rules! each {
    ($bank:expr, $b:ident => $body:expr) => {
        match $bank {
            AnyBank::D1($b) => $body,
            AnyBank::D2($b) => $body,
            AnyBank::D3($b) => $body,
        }
    };
}

#[pymethods]
impl CaBank {
    /// `x0` (B, 3, D); `p0` (3D, 3D) for every edge or (B, 3D, 3D); `r` (D, D) or (B, D, D).
    #[new]
    fn new(
        dt: f64,
        sigma_w: f64,
        x0: PyReadonlyArrayDyn<'_, f64>,
        p0: PyReadonlyArrayDyn<'_, f64>,
        r: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<Self> {
        let s = x0.shape().to_vec();
        if s.len() != 3 || s[0] == 0 || s[1] != 3 || !(1..=3).contains(&s[2]) {
            return Err(err(format!(
                "x0: expected shape (B, 3, D) (rows: position, velocity, acceleration) with B ≥ 1 and D in 1..=3, got {s:?}"
            )));
        }
        let (b, d) = (s[0], s[2]);
        let n = 3 * d;
        let x = flat(&x0, "x0", &[b, 3, d])?;
        let p_shared = p0.shape() == [n, n];
        let p_want: Vec<usize> = if p_shared { vec![n, n] } else { vec![b, n, n] };
        let p = flat(&p0, "P0", &p_want)?;
        check_covs(&p, n, p_shared, "P0", false)?;
        let r_shared = r.shape() == [d, d];
        let r_want: Vec<usize> = if r_shared { vec![d, d] } else { vec![b, d, d] };
        let rv = flat(&r, "R", &r_want)?;
        check_covs(&rv, d, r_shared, "R", true)?;
        let bank = match d {
            1 => AnyBank::D1(Bank::new(b, dt, sigma_w, &x, &p, p_shared, &rv, r_shared)?),
            2 => AnyBank::D2(Bank::new(b, dt, sigma_w, &x, &p, p_shared, &rv, r_shared)?),
            _ => AnyBank::D3(Bank::new(b, dt, sigma_w, &x, &p, p_shared, &rv, r_shared)?),
        };
        Ok(Self { b, d, bank })
    }

    /// Prediction (Li & Rajan eqs. 6, 7): `γ̂ ← F γ̂`, `Λ ← F Λ Fᵀ + Q`.
    fn predict(&mut self) {
        each!(&mut self.bank, k => k.batch.predict(&k.model));
    }

    /// Correction of the observed edges (Joseph form): `y` (B, D), `observed` (B,) booleans;
    /// rows not observed are ignored (they may hold NaN). A non-finite observed row is refused
    /// before anything changes.
    fn update(
        &mut self,
        y: PyReadonlyArrayDyn<'_, f64>,
        observed: PyReadonlyArrayDyn<'_, bool>,
    ) -> PyResult<()> {
        let (b, d) = (self.b, self.d);
        if y.shape() != [b, d] {
            return Err(err(format!(
                "y: expected shape {:?}, got {:?}",
                [b, d],
                y.shape()
            )));
        }
        if observed.shape() != [b] {
            return Err(err(format!(
                "observed: expected shape {:?}, got {:?}",
                [b],
                observed.shape()
            )));
        }
        let yv: Vec<f64> = y.as_array().iter().copied().collect();
        let mask: Vec<bool> = observed.as_array().iter().copied().collect();
        for e in 0..b {
            if mask[e] && !yv[e * d..(e + 1) * d].iter().all(|v| v.is_finite()) {
                return Err(err(format!(
                    "y: row {e} is observed but not finite (mark a missing observation with observed = False or a NaN row)"
                )));
            }
        }
        each!(&mut self.bank, k => k.update(b, &yv, &mask));
        Ok(())
    }

    /// `(x̂ (B, 3, D), P (B, 3D, 3D))`.
    #[allow(clippy::type_complexity)]
    fn state<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray3<f64>>)> {
        let (b, d) = (self.b, self.d);
        let (x, p) = each!(&self.bank, k => k.state(b));
        let x = PyArray1::from_vec(py, x).reshape([b, 3, d])?;
        let p = PyArray1::from_vec(py, p).reshape([b, 3 * d, 3 * d])?;
        Ok((x, p))
    }
}
