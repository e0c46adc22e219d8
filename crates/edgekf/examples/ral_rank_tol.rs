//! The RAL's rank threshold against the closed-loop divergence of GA-RKF at low edge
//! availability (Li & Rajan Figs. 8 and 11 at λ = 0.2): the same runs with `ral_rank_tol` from
//! 1e-6 (numerically singular H only) to 0.3 (σ_min(H) ≥ 0.3 σ_max(H)).
//!
//! ```sh
//! cargo run --release -p edgekf --example ral_rank_tol
//! ```

use edgekf::scenario::Scenario;
use edgekf::sim::{self, Quiet, Results};
use edgekf_io::reproductions;

fn window_mean(res: &Results, label: &str, metric: &str, from: f64, to: f64) -> f64 {
    let v = res.values(label, metric).expect("metric");
    let runs = res.runs.len();
    let (mut s, mut n) = (0.0, 0.0);
    for (k, &step) in res.steps.iter().enumerate() {
        let t = step as f64 * res.dt;
        if t >= from && t <= to {
            for r in 0..runs {
                s += v[k * runs + r];
                n += 1.0;
            }
        }
    }
    s / n
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for (name, point) in [("garkf-fig8", 1usize), ("garkf-fig11", 1)] {
        let e = reproductions::find(name).ok_or("no such reproduction")?;
        println!("{name}, sweep value {point}:");
        println!(
            "  {:>8}  {:>14}  {:>14}  {:>14}  {:>14}  {:>10}",
            "rank_tol", "θ err 5–30 s", "θ err 30–60 s", "δ 0–60 s", "ε 30–60 s", "completed"
        );
        for tol in [1e-6, 1e-2, 0.05, 0.1, 0.2, 0.3] {
            let mut spec = edgekf_io::spec_from_toml(e.text)?;
            spec.plots.clear();
            for est in &mut spec.estimators {
                if est.0.get("kind").and_then(|k| k.as_str()) == Some("garkf") {
                    est.0.insert("ral_rank_tol".into(), tol.into());
                }
            }
            let sc = Scenario::from_spec(&spec, None)?;
            let sc = sc.sweep_points()?.swap_remove(point).scenario;
            let res = sim::run(&sc, &Quiet)?;
            let label = sc
                .estimators()
                .iter()
                .map(|d| d.label().to_string())
                .find(|l| l == "garkf" || l == "GA-RKF")
                .ok_or("no garkf")?;
            let est = res.estimator(&label).ok_or("no results")?;
            println!(
                "  {tol:>8}  {:>14.4e}  {:>14.4e}  {:>14.4e}  {:>14.4e}  {:>10}",
                window_mean(&res, &label, "theta_error", 5.0, 30.0),
                window_mean(&res, &label, "theta_error", 30.0, 60.0),
                window_mean(&res, &label, "tracking_error", 0.0, 60.0),
                window_mean(&res, &label, "est_error", 30.0, 60.0),
                est.valid == res.steps.len()
            );
        }
    }
    Ok(())
}
