//! Scale: a 1,000-agent 2-trilateration framework, one run, closed-loop steps per second of the
//! RKF and the JRKF, with white process noise (`Q = σ_w² I`) and with the dense spatial kernel of
//! the thesis (ND × ND factor), and what the CRKF would cost at that size.
//!
//! `cargo bench -p edgekf --bench scale [-- N STEPS THREADS]` (default N = 1000, 2000 steps, one
//! thread; with more, one run's large steps are shared between them: the JRKF's per-agent
//! recursions and the noise factor).

use std::time::Instant;

use edgekf::design::{self, generators};
use edgekf::noise::Kernel;
use edgekf::scenario::{EstimatorEntry, FrameworkSpec, Scenario, ScenarioSpec};
use rand::SeedableRng;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let n = args.first().copied().unwrap_or(1000);
    let steps = args.get(1).copied().unwrap_or(2000);
    let threads = args.get(2).copied().unwrap_or(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    let spec_fw = framework(n, threads);
    for (kernel, label) in [
        (Kernel::White, "white Q"),
        (Kernel::default(), "thesis kernel (4.14), dense Q"),
    ] {
        let only = std::env::var("SCALE_ONLY").ok();
        for est in ["rkf", "jrkf", "crkf"] {
            if only.as_deref().is_some_and(|o| o != est && o != label) {
                continue;
            }
            let t = Instant::now();
            let sc = scenario(&spec_fw, est, kernel, steps);
            let setup = t.elapsed().as_secs_f64();
            let cost = edgekf::sim::cost(&sc, 1, 1);
            if est == "crkf" {
                println!(
                    "  {label}: crkf — estimated {} for {steps} steps ({} in its (N−1)D = {}-dimensional covariance steps), {} of memory: refused above `--max-hours`",
                    edgekf::sim::cost::human_seconds(cost.seconds),
                    edgekf::sim::cost::human_seconds(cost.shared_seconds),
                    (n - 1) * 2,
                    edgekf::sim::cost::human_bytes(cost.bytes)
                );
                continue;
            }
            let t = Instant::now();
            let res = pool
                .install(|| edgekf::sim::run(&sc, &edgekf::sim::Quiet))
                .expect("not cancelled");
            let wall = t.elapsed().as_secs_f64();
            println!(
                "  {label}: {est:<5} {:8.0} steps/s ({:.1} ns per agent-step; setup {setup:.1} s, estimate {}; {:?})",
                steps as f64 / wall,
                wall / (steps * n) as f64 * 1e9,
                edgekf::sim::cost::human_seconds(cost.seconds),
                res.estimators[0].outcome
            );
        }
    }
}

/// A designed 2-trilateration framework of `n` agents (seed 3), as a scenario's framework.
fn framework(n: usize, threads: usize) -> FrameworkSpec {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
    let t = Instant::now();
    let cand = generators::trilateration(n, 2, 3, &mut rng);
    let d = design::design(&cand, design::Method::Yang).expect("trilateration graphs design");
    let fw = d.framework;
    println!(
        "framework: N = {n}, {} links (designed by `{}` in {:.1} s); {threads} thread(s)",
        fw.graph().links().len(),
        d.method,
        t.elapsed().as_secs_f64()
    );
    FrameworkSpec {
        dim: Some(2),
        config: Some((0..n).map(|i| fw.point(i).to_vec()).collect()),
        edges: Some(fw.graph().links().iter().map(|&(i, j)| [i, j]).collect()),
        weights: Some(fw.weights().to_vec()),
        leaders: Some(fw.leaders().to_vec()),
        name: Some(format!("trilateration-{n}")),
        ..FrameworkSpec::default()
    }
}

/// One run of `est` on `fw` under `kernel` for `steps` steps, Δt at 3/4 of the closed loop's
/// step bound.
fn scenario(fw: &FrameworkSpec, est: &str, kernel: Kernel, steps: usize) -> Scenario {
    let mut spec = ScenarioSpec::minimal("scale", &[]);
    spec.framework = fw.clone();
    spec.estimators = vec![EstimatorEntry::kind(est)];
    spec.noise.kernel = kernel;
    spec.sim.runs = 1;
    spec.sim.steps = steps;
    spec.sim.every = steps;
    let lmax = {
        let mut s = spec.clone();
        s.sim.allow_divergence = true;
        let sc = Scenario::from_spec(&s, None).expect("valid");
        sc.step_bound() / sc.dt()
    };
    spec.sim.dt = 1.5 / lmax;
    Scenario::from_spec(&spec, None).expect("valid")
}
