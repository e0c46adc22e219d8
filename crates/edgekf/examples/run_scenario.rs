//! A study from code: the EUSIPCO setup (thesis hexagon, σ_w = 0.001, σ_v = 0.1) with its five
//! estimators, at a reduced size, and a steady-state table — what `edgekf run` does, without
//! files. Also shows changing a shipped scenario and reading per-run values.
//!
//! ```sh
//! cargo run -p edgekf --example run_scenario
//! ```

use edgekf::scenario::{Scenario, ScenarioSpec};
use edgekf::sim::{self, Observer};
use edgekf_io::reproductions;

/// Progress on stderr, every tenth of the run-steps.
struct Dots(std::sync::atomic::AtomicU64, u64);

impl Observer for Dots {
    fn on_progress(&self, n: u64) {
        let done = self.0.fetch_add(n, std::sync::atomic::Ordering::Relaxed) + n;
        if (done - n) * 10 / self.1 != done * 10 / self.1 {
            eprint!(".");
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // 1. A shipped scenario (the EUSIPCO / thesis ch. 5 study), smaller.
    let entry = reproductions::find("eusipco-fig4b").ok_or("no such reproduction")?;
    let sc = entry.scenario()?.with_size(Some(4), Some(3000), Some(30))?;
    let dots = Dots(0.into(), (sc.runs() * sc.steps()) as u64);
    let res = sim::run(&sc, &dots)?;
    eprintln!();
    println!(
        "{}: {} runs × {} steps of {} s",
        sc.name(),
        sc.runs(),
        sc.steps(),
        sc.model().dt()
    );
    println!("estimator   ε, last second [m]   tr Σ, last [m²]   mean ε² / tr Σ");
    let from = res.steps.iter().position(|&k| k >= 2000).unwrap_or(0);
    for label in res.labels() {
        let e = res.series(label, "est_error").ok_or("no est_error")?;
        let e2 = res.series(label, "est_error_sq").ok_or("no est_error_sq")?;
        let tr = res.series(label, "cov_trace").ok_or("no cov_trace")?;
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        println!(
            "{label:<10}  {:>18.4e}  {:>16.4e}  {:>15.3}",
            mean(&e.mean[from..]),
            tr.mean.last().copied().unwrap_or(f64::NAN),
            mean(&e2.mean[from..]) / mean(&tr.mean[from..])
        );
    }

    // 2. A scenario built in code, and the per-run values behind the means.
    let mut spec = ScenarioSpec::minimal("two-filters", &["rkf", "jrkf"]);
    spec.sim.steps = 1000;
    spec.sim.runs = 3;
    spec.sim.every = 250;
    let sc = Scenario::from_spec(&spec, None)?;
    let res = sim::run(&sc, &sim::Quiet)?;
    let runs = res.runs.len();
    for label in res.labels() {
        let v = res.values(label, "est_error").ok_or("no est_error")?;
        let last = &v[(res.steps.len() - 1) * runs..];
        println!(
            "{label}: ε at step {} per run: {last:.4?}",
            res.steps.last().unwrap()
        );
    }
    Ok(())
}
