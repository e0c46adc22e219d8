//! Classical RK4 simulation of the closed loop: plant (eqs. 1–4, 14) and the `n` observers (eq. 19), and of the
//! linear error system (eq. 21) for comparison.
//!
//! The joint state is `s = [x; x̂_1; …; x̂_n]`. The plant uses the control law of eqs. (3)–(4) directly (true
//! centroid and true G⁺ relative positions; robot i's estimates for G⁻), not the compact form (14), so that
//! comparing with eq. (21) checks the derivation.

use crate::spec::Scenario;
use nalgebra::DVector;

/// Time series sampled on the output grid.
#[derive(Debug, Clone)]
pub struct Trajectory {
    /// Sample times (s).
    pub times: Vec<f64>,
    /// True state `x(t)` per sample.
    pub x: Vec<DVector<f64>>,
    /// Estimates `x̂_i(t)` per sample, per robot.
    pub xhat: Vec<Vec<DVector<f64>>>,
}

impl Trajectory {
    /// Robot `i`'s estimation error `x̂_i − x` at sample `k`.
    pub fn error(&self, k: usize, i: usize) -> DVector<f64> {
        &self.xhat[k][i] - &self.x[k]
    }

    /// `sqrt(Σ_i ‖x̂_i − x‖²)` at sample `k`.
    pub fn total_error(&self, k: usize) -> f64 {
        (0..self.xhat[k].len())
            .map(|i| self.error(k, i).norm_squared())
            .sum::<f64>()
            .sqrt()
    }

    /// The stacked error `E = [e_1; …; e_n]` at sample `k`.
    pub fn stacked_error(&self, k: usize) -> DVector<f64> {
        let n = self.xhat[k].len();
        let dim = self.x[k].len();
        DVector::from_fn(n * dim, |r, _| {
            self.xhat[k][r / dim][r % dim] - self.x[k][r % dim]
        })
    }
}

/// Scratch buffers for the right-hand side (allocated once per run).
struct Workspace {
    bu: DVector<f64>,
    u: Vec<f64>,
    omega: Vec<f64>,
    nu: Vec<DVector<f64>>,
    innov: Vec<DVector<f64>>,
    cons: DVector<f64>,
}

fn rhs(sc: &Scenario, ws: &mut Workspace, t: f64, s: &DVector<f64>, out: &mut DVector<f64>) {
    let model = sc.model();
    let n = model.n;
    let dim = model.dim();
    let x = &s.as_slice()[..dim];
    let xhat: Vec<&[f64]> = (0..n)
        .map(|i| &s.as_slice()[(i + 1) * dim..(i + 2) * dim])
        .collect();
    model.control_into(t, x, &xhat, &mut ws.u);
    match sc.disturbance() {
        Some(d) => {
            d.omega_into(t, &mut ws.omega);
            for i in 0..n {
                d.nu_into(i, t, ws.nu[i].as_mut_slice());
            }
        }
        None => ws.omega.fill(0.0),
    }
    out.fill(0.0);
    for k in 0..2 * n {
        out[k] = ws.u[k] + ws.omega[k];
    }
    model.input_into(t, &mut ws.bu);
    let xv = s.rows(0, dim);
    for i in 0..n {
        let ob = &sc.observers()[i];
        let xi = s.rows((i + 1) * dim, dim);
        // innovation y_i − H_i x̂_i = H_i (x − x̂_i) + ν_i
        ws.innov[i].gemv(1.0, &model.h[i], &xv, 0.0);
        ws.innov[i].gemv(-1.0, &model.h[i], &xi, 1.0);
        if sc.disturbance().is_some() {
            ws.innov[i] += &ws.nu[i];
        }
        // consensus Σ_j a_ij (x̂_j − x̂_i)
        ws.cons.fill(0.0);
        for &(j, a) in &model.communicating[i] {
            let xj = s.rows((j + 1) * dim, dim);
            ws.cons.axpy(a, &xj, 1.0);
            ws.cons.axpy(-a, &xi, 1.0);
        }
        let mut o = out.rows_mut((i + 1) * dim, dim);
        o.gemv(1.0, &model.a, &xi, 0.0);
        o += &ws.bu;
        o.gemv(1.0, &ob.k, &ws.innov[i], 1.0);
        o.gemv(sc.gamma(), &ob.w_proj, &ws.cons, 1.0);
    }
}

/// Simulates the scenario with its own step and output grid.
pub fn simulate(sc: &Scenario) -> Trajectory {
    simulate_with_step(sc, sc.step(), sc.steps(), sc.output_stride())
}

/// Simulates with RK4 step `h` for `steps` steps, sampling every `stride` steps (and at `t = 0`).
pub fn simulate_with_step(sc: &Scenario, h: f64, steps: usize, stride: usize) -> Trajectory {
    let model = sc.model();
    let n = model.n;
    let dim = model.dim();
    let total = (n + 1) * dim;
    let mut s = DVector::zeros(total);
    s.rows_mut(0, dim).copy_from(sc.x0());
    for i in 0..n {
        s.rows_mut((i + 1) * dim, dim).copy_from(&sc.xhat0()[i]);
    }
    let mut ws = Workspace {
        bu: DVector::zeros(dim),
        u: vec![0.0; 2 * n],
        omega: vec![0.0; 2 * n],
        nu: (0..n)
            .map(|i| DVector::zeros(model.measurement_rows(i)))
            .collect(),
        innov: (0..n)
            .map(|i| DVector::zeros(model.measurement_rows(i)))
            .collect(),
        cons: DVector::zeros(dim),
    };
    let (mut k1, mut k2, mut k3, mut k4, mut tmp) = (
        DVector::zeros(total),
        DVector::zeros(total),
        DVector::zeros(total),
        DVector::zeros(total),
        DVector::zeros(total),
    );
    let samples = steps / stride.max(1) + 1;
    let mut traj = Trajectory {
        times: Vec::with_capacity(samples),
        x: Vec::with_capacity(samples),
        xhat: Vec::with_capacity(samples),
    };
    let record = |traj: &mut Trajectory, t: f64, s: &DVector<f64>| {
        traj.times.push(t);
        traj.x.push(s.rows(0, dim).into_owned());
        traj.xhat.push(
            (0..n)
                .map(|i| s.rows((i + 1) * dim, dim).into_owned())
                .collect(),
        );
    };
    record(&mut traj, 0.0, &s);
    for k in 0..steps {
        let t = Scenario::time_of_step(k, h);
        let t_next = Scenario::time_of_step(k + 1, h);
        let t_mid = t + 0.5 * h;
        rhs(sc, &mut ws, t, &s, &mut k1);
        tmp.copy_from(&s);
        tmp.axpy(0.5 * h, &k1, 1.0);
        rhs(sc, &mut ws, t_mid, &tmp, &mut k2);
        tmp.copy_from(&s);
        tmp.axpy(0.5 * h, &k2, 1.0);
        rhs(sc, &mut ws, t_mid, &tmp, &mut k3);
        tmp.copy_from(&s);
        tmp.axpy(h, &k3, 1.0);
        rhs(sc, &mut ws, t_next, &tmp, &mut k4);
        s.axpy(h / 6.0, &k1, 1.0);
        s.axpy(h / 3.0, &k2, 1.0);
        s.axpy(h / 3.0, &k3, 1.0);
        s.axpy(h / 6.0, &k4, 1.0);
        if (k + 1) % stride == 0 {
            record(&mut traj, t_next, &s);
        }
    }
    traj
}

/// Integrates the linear error dynamics of eq. (21), `Ė = 𝒜 E + diag(K_i) ν(t) − 1_n ⊗ G ω(t)` with
/// `𝒜` = [`crate::observer::error_system_matrix`], from `E(0) = x̂(0) − x(0)` with the same RK4 grid as
/// [`simulate`]. Returns `E` at the output samples.
pub fn simulate_error_system(sc: &Scenario) -> Vec<DVector<f64>> {
    let model = sc.model();
    let n = model.n;
    let dim = model.dim();
    let a = crate::observer::error_system_matrix(
        model,
        sc.observers(),
        sc.gamma(),
        crate::observer::ConsensusSign::Eq19,
    );
    let mut e = DVector::from_fn(n * dim, |r, _| {
        sc.xhat0()[r / dim][r % dim] - sc.x0()[r % dim]
    });
    let mut omega = vec![0.0; 2 * n];
    let mut nu: Vec<DVector<f64>> = (0..n)
        .map(|i| DVector::zeros(model.measurement_rows(i)))
        .collect();
    let f = |t: f64,
             e: &DVector<f64>,
             omega: &mut Vec<f64>,
             nu: &mut Vec<DVector<f64>>|
     -> DVector<f64> {
        let mut out = &a * e;
        if let Some(d) = sc.disturbance() {
            d.omega_into(t, omega);
            for (i, nu_i) in nu.iter_mut().enumerate() {
                d.nu_into(i, t, nu_i.as_mut_slice());
                let kv = &sc.observers()[i].k * &*nu_i;
                let mut blk = out.rows_mut(i * dim, dim);
                blk += kv;
                for c in 0..2 * n {
                    blk[c] -= omega[c];
                }
            }
        }
        out
    };
    let h = sc.step();
    let mut out = vec![e.clone()];
    for k in 0..sc.steps() {
        let t = Scenario::time_of_step(k, h);
        let t_next = Scenario::time_of_step(k + 1, h);
        let t_mid = t + 0.5 * h;
        let k1 = f(t, &e, &mut omega, &mut nu);
        let k2 = f(t_mid, &(&e + &k1 * (0.5 * h)), &mut omega, &mut nu);
        let k3 = f(t_mid, &(&e + &k2 * (0.5 * h)), &mut omega, &mut nu);
        let k4 = f(t_next, &(&e + &k3 * h), &mut omega, &mut nu);
        e += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        if (k + 1) % sc.output_stride() == 0 {
            out.push(e.clone());
        }
    }
    out
}
