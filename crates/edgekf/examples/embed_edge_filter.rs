//! One agent's edge filters, embedded without the Monte Carlo engine: agent 0 of a small team
//! tracks its edges to three neighbours with one [`EdgeCov`] each (EUSIPCO eq. (5), the RKF), from
//! the mean of T noisy relative measurements per step and the inputs its neighbours send, and
//! steers with the estimates. Prints the estimation error and the filter's own uncertainty.
//!
//! ```sh
//! cargo run -p edgekf --example embed_edge_filter
//! ```

use edgekf::estimate::batch::EdgeCov;
use nalgebra::{Matrix2, Vector2};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

fn main() {
    let (dt, t_samples, steps): (f64, f64, usize) = (1e-3, 10.0, 5000);
    // Noise: process σ_w = 0.001 per agent and step; measurements σ_v = 0.1, ρ = 0.3.
    let q_agent: f64 = 1e-6;
    let q = Matrix2::identity() * 2.0 * q_agent; // Q_ij: both ends' process noise
    let r = Matrix2::new(1e-2, 3e-3, 3e-3, 1e-2);
    let w = r / t_samples;
    let chol = r.cholesky().expect("R is positive definite").l() / t_samples.sqrt();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    let mut normal2 = || {
        Vector2::new(
            StandardNormal.sample(&mut rng),
            StandardNormal.sample(&mut rng),
        )
    };

    // The team: agent 0 (ours) and three neighbours that hold still except for noise and a slow
    // drift they announce as their input. Agent 0 wants to sit at the centroid of their targets.
    let target: [Vector2<f64>; 3] = [
        Vector2::new(1.0, 0.0),
        Vector2::new(-0.5, 0.866),
        Vector2::new(-0.5, -0.866),
    ];
    let mut me = Vector2::new(2.0, 2.0);
    let mut them: Vec<Vector2<f64>> = vec![
        Vector2::new(1.2, 0.1),
        Vector2::new(-0.4, 1.0),
        Vector2::new(-0.7, -0.8),
    ];
    // One filter per edge (0, j): estimate ẑ_0j of z_0 − z_j and its covariance.
    let mut filters: Vec<(EdgeCov<2>, Vector2<f64>)> = (0..3)
        .map(|_| (EdgeCov::new(Matrix2::identity() * 2.0), Vector2::zeros()))
        .collect();
    let mut u_me = Vector2::zeros();
    println!("   t [s]   ε = ‖z − ẑ‖ [m]   √tr Σ [m]   ‖z_0 − goal‖ [m]");
    for k in 1..=steps {
        let t = k as f64 * dt;
        // The neighbours' inputs, received over the links.
        let u_them: Vec<Vector2<f64>> = (0..3)
            .map(|j| 0.05 * Vector2::new((t + j as f64).sin(), (t + j as f64).cos()))
            .collect();
        // The world moves with last step's inputs and process noise.
        me += dt * u_me + q_agent.sqrt() * normal2();
        for j in 0..3 {
            them[j] += dt * u_them[j] + q_agent.sqrt() * normal2();
        }
        // Predict with both inputs (5c), covariance and gain (5d, 5e, 5g), update (5f).
        for (j, (cov, z_hat)) in filters.iter_mut().enumerate() {
            *z_hat += dt * (u_me - u_them[j]);
            cov.step(&q, &w, None, true)
                .expect("the innovation covariance is positive definite");
            let y_mean = (me - them[j]) + chol * normal2();
            *z_hat += cov.gain * (y_mean - *z_hat);
        }
        // Control on the estimates: go to the neighbours' centroid offset by the targets' one,
        // u = −Σ_j (ẑ_0j − (0 − target_j)) / 3.
        u_me = -filters
            .iter()
            .zip(&target)
            .map(|((_, z_hat), p)| z_hat + p)
            .sum::<Vector2<f64>>()
            / 3.0;
        if k == 1 || k % 1000 == 0 {
            let err: f64 = filters
                .iter()
                .enumerate()
                .map(|(j, (_, z_hat))| (me - them[j] - z_hat).norm_squared())
                .sum::<f64>()
                .sqrt();
            let tr: f64 = filters.iter().map(|(c, _)| c.sigma.trace()).sum();
            let goal = them
                .iter()
                .zip(&target)
                .map(|(z, p)| z - p)
                .sum::<Vector2<f64>>()
                / 3.0;
            println!(
                "{t:8.3}   {err:15.3e}   {:9.3e}   {:16.3e}",
                tr.sqrt(),
                (me - goal).norm()
            );
        }
    }
    let tr: f64 = filters.iter().map(|(c, _)| c.sigma.trace()).sum();
    assert!(tr < 1e-2, "the filters converged");
}
