//! `edgekf bench`: closed-loop speed per estimator on the EUSIPCO scenario, and the wall time of
//! reproducing every figure. Speed targets live here, never in timed tests.

use std::time::Instant;

use anyhow::Result;
use edgekf::scenario::{EstimatorEntry, ScenarioSpec};

use crate::{registry, Overrides};

/// Options of `edgekf bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Steps per estimator run.
    #[arg(long, default_value_t = 30_000)]
    steps: usize,
    /// Monte Carlo runs.
    #[arg(long, default_value_t = 50)]
    runs: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also time `reproduce all` (writes into a temporary directory).
    #[arg(long)]
    reproduce: bool,
}

/// Runs the benchmark and prints a table.
pub fn run(args: &BenchArgs) -> Result<()> {
    let pool = crate::pool(args.threads)?;
    let text = registry::find("eusipco-fig4a").expect("registered").text;
    let base: ScenarioSpec = toml::from_str(text)?;
    println!(
        "closed-loop speed on the EUSIPCO scenario (N = 10, M = 60, T = 10), {} runs × {} steps, {} thread(s)",
        args.runs,
        args.steps,
        pool.current_num_threads()
    );
    println!(
        "{:<10} {:>10} {:>16} {:>14}",
        "estimator", "wall [s]", "agent-steps/s", "ns/agent-step"
    );
    let kinds: [EstimatorEntry; 7] = [
        EstimatorEntry::Name("oracle".into()),
        EstimatorEntry::Name("none".into()),
        EstimatorEntry::Name("mle".into()),
        EstimatorEntry::Table(edgekf::scenario::EstimatorTable {
            kind: "mmse".into(),
            label: None,
            samples: None,
            prior_var: Some(1e-3),
            p_fail: None,
        }),
        EstimatorEntry::Name("rkf".into()),
        EstimatorEntry::Name("jrkf".into()),
        EstimatorEntry::Name("crkf".into()),
    ];
    for k in kinds
        .iter()
        .cloned()
        .chain(std::iter::once(EstimatorEntry::Name("all".into())))
    {
        let mut spec = base.clone();
        spec.plots.clear();
        let label = match &k {
            EstimatorEntry::Name(n) if n == "all" => {
                spec.estimators = kinds[1..].to_vec();
                "all six".to_string()
            }
            EstimatorEntry::Name(n) => {
                spec.estimators = vec![k.clone()];
                n.clone()
            }
            EstimatorEntry::Table(t) => {
                spec.estimators = vec![k.clone()];
                t.kind.clone()
            }
        };
        spec.sim.steps = args.steps;
        spec.sim.runs = args.runs;
        let sc = edgekf::scenario::Scenario::from_spec(&spec, None)?;
        let t = Instant::now();
        let _ = pool.install(|| edgekf::sim::run(&sc, &edgekf::sim::Quiet));
        let wall = t.elapsed().as_secs_f64();
        let agent_steps = (sc.framework.agents() * sc.runs * sc.steps * sc.estimators.len()) as f64;
        println!(
            "{label:<10} {wall:>10.3} {:>16.3e} {:>14.1}",
            agent_steps / wall,
            wall / agent_steps * 1e9
        );
    }
    if args.reproduce {
        let dir = std::env::temp_dir().join(format!("edgekf-bench-{}", std::process::id()));
        let t = Instant::now();
        let over = Overrides {
            threads: args.threads,
            ..Overrides::default()
        };
        crate::reproduce(&["all".to_string()], &dir, &over)?;
        println!(
            "reproduce all ({} figures, paper scale): {:.2} s",
            registry::ENTRIES.len(),
            t.elapsed().as_secs_f64()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(())
}
