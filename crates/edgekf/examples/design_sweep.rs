//! The full robustness sweep of issue 11, with counts and times:
//! `cargo run --release -p edgekf --example design_sweep [-- SEEDS]` (default 3 seeds: 288
//! instances, each designed by `sdp` and `sparse`).
//!
//! Families (see `generators::family`): D-trilateration backbones (`D + 1` nearest earlier
//! neighbours per agent) plus the `k` nearest neighbours of every agent, `k ∈ {0, 2, 4}`,
//! N ∈ {10, 20, 50, 100}, D ∈ {2, 3}, four box shapes (unit density, ×1e-3, ×1e3, 10:1). Every
//! instance must either design a framework that passes every check or be refused with a named
//! condition; a solver failure is counted separately (and must not occur).

use std::collections::BTreeMap;
use std::time::Instant;

use edgekf::design::generators::{self, Extent};
use edgekf::design::{self, CheckReport, DesignError, Method};

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("SEEDS is a number"))
        .unwrap_or(3);
    let instances = generators::family(
        &[10, 20, 50, 100],
        &[2, 3],
        &[0, 2, 4],
        &Extent::ALL,
        0..seeds,
    );
    println!(
        "{} instances × 2 methods; columns: name, method, outcome, solver, iterations, gap, ratio, seconds",
        instances.len()
    );
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut times: BTreeMap<(usize, &'static str), (f64, f64, usize)> = BTreeMap::new();
    let mut gaps: Vec<f64> = Vec::new();
    let total = Instant::now();
    for c in &instances {
        let n = c.config.len();
        for (name, method) in [("sdp", Method::Sdp), ("sparse", Method::Sparse)] {
            let t = Instant::now();
            let result = design::design(c, method);
            let secs = t.elapsed().as_secs_f64();
            let entry = times.entry((n, name)).or_insert((0.0, 0.0, 0));
            entry.0 += secs;
            entry.1 = entry.1.max(secs);
            entry.2 += 1;
            let outcome = match &result {
                Ok(d) => {
                    let r = CheckReport::from_framework(&d.framework);
                    if r.passed() {
                        gaps.push(d.gap);
                        println!(
                            "{}\t{name}\tdesigned\t{}\t{}\t{:.1e}\t{:.3e}\t{secs:.3}",
                            c.name,
                            d.solver,
                            d.newton_steps,
                            d.gap,
                            r.max_eigenvalue() / r.stress_gap()
                        );
                        format!("designed ({})", d.solver)
                    } else {
                        println!("{}\t{name}\tFAILED CHECKS\n{r}", c.name);
                        "designed but failed its checks".into()
                    }
                }
                Err(e) => {
                    println!("{}\t{name}\t{e}\t\t\t\t\t{secs:.3}", c.name);
                    match e {
                        DesignError::NotUniversallyRigid(_) => {
                            "refused: not universally rigid".into()
                        }
                        DesignError::NonGeneric(_) => "refused: non-generic".into(),
                        DesignError::Solver { status, .. } => format!("solver failure: {status}"),
                        other => format!("other error: {other}"),
                    }
                }
            };
            *counts.entry(outcome).or_default() += 1;
        }
    }
    println!("\noutcomes:");
    for (k, v) in &counts {
        println!("  {v:5}  {k}");
    }
    gaps.sort_by(f64::total_cmp);
    let pct = |q: f64| gaps[((gaps.len() - 1) as f64 * q).round() as usize];
    if !gaps.is_empty() {
        println!(
            "relative optimality gap of the designs: median {:.1e}, 90% {:.1e}, max {:.1e}; {} of {} above 1e-6",
            pct(0.5),
            pct(0.9),
            pct(1.0),
            gaps.iter().filter(|&&g| g > 1e-6).count(),
            gaps.len()
        );
    }
    println!("seconds per design (mean / max):");
    for ((n, m), (sum, max, k)) in &times {
        println!(
            "  N = {n:3}  {m:6}  {:.3} / {max:.3}  ({k} designs)",
            sum / *k as f64
        );
    }
    println!("total {:.1} s", total.elapsed().as_secs_f64());
}
