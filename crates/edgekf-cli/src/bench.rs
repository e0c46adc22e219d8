//! `edgekf bench`: closed-loop speed per estimator on the EUSIPCO scenario, and the wall time of
//! reproducing every figure. Speed targets live here, never in timed tests.

use std::time::Instant;

use anyhow::Result;
use edgekf::scenario::{EstimatorEntry, Scenario, ScenarioSpec};
use edgekf::sim::cost::human_seconds;

use crate::Overrides;
use edgekf_io::reproductions as registry;

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
    /// Also time the GA-RKF study (Li & Rajan Fig. 11 at λ = 0.4 without its sweep: the hexagon,
    /// the 60 s maneuver, `--runs` runs): none, rkf-ca and garkf alone and together.
    #[arg(long)]
    garkf: bool,
    /// Also check the cost model (what `--max-hours` and the long-study notice read) against
    /// this machine: every shipped filter scenario, each estimator alone without its sweep,
    /// estimated and measured.
    #[arg(long)]
    cost: bool,
}

/// Runs the benchmark and prints a table.
pub fn run(args: &BenchArgs) -> Result<()> {
    let pool = crate::pool(args.threads)?;
    let text = registry::find("eusipco-fig4a").expect("registered").text;
    let base = edgekf_io::spec_from_toml(text)?;
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
    let kinds: Vec<EstimatorEntry> = vec![
        EstimatorEntry::kind("oracle"),
        EstimatorEntry::kind("none"),
        EstimatorEntry::kind("mle"),
        EstimatorEntry::kind("mmse").with("prior_var", 1e-3),
        EstimatorEntry::kind("rkf"),
        EstimatorEntry::kind("jrkf"),
        EstimatorEntry::kind("crkf"),
    ];
    let mut sets: Vec<(String, Vec<EstimatorEntry>)> = kinds
        .iter()
        .map(|k| {
            (
                k.0["kind"].as_str().unwrap_or("?").to_string(),
                vec![k.clone()],
            )
        })
        .collect();
    sets.push(("all six".into(), kinds[1..].to_vec()));
    for (label, set) in sets {
        let mut spec = base.clone();
        spec.plots.clear();
        spec.estimators = set;
        spec.sim.steps = args.steps;
        spec.sim.runs = args.runs;
        time_row(&pool, &spec, &format!("{label:<10}"), true)?;
    }
    if args.garkf {
        garkf(args, &pool)?;
    }
    if args.cost {
        cost_model(&pool)?;
    }
    if args.reproduce {
        let dir = std::env::temp_dir().join(format!("edgekf-bench-{}", std::process::id()));
        let t = Instant::now();
        let over = Overrides {
            threads: args.threads,
            ..Overrides::default()
        };
        crate::reproduce(&["all".to_string()], &dir, &over, false, false)?;
        println!(
            "reproduce all ({} figures, paper scale): {:.2} s",
            registry::ENTRIES.len(),
            t.elapsed().as_secs_f64()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(())
}

/// The GA-RKF speed (issue target: the three together ≥ 10⁶ agent-steps/s on 2 cores). An
/// agent-step is one agent of one run advancing one step in the study, whatever the number of
/// estimators (each estimator closes its own loop).
fn garkf(args: &BenchArgs, pool: &rayon::ThreadPool) -> Result<()> {
    let text = registry::find("garkf-fig11").expect("registered").text;
    let mut base = edgekf_io::spec_from_toml(text)?;
    base.plots.clear();
    base.sweep = None;
    base.sim.runs = args.runs;
    // The three fixed filters of the target (Fig. 11 also draws an adaptive GA-RKF).
    let all: Vec<EstimatorEntry> = base
        .estimators
        .iter()
        .filter(|e| e.0.get("adaptive").is_none())
        .cloned()
        .collect();
    println!(
        "\nGA-RKF study (Li & Rajan Fig. 11 at λ = 0.4: hexagon, N = 10, 60 s maneuver), {} runs × {} steps, {} thread(s)",
        base.sim.runs,
        base.sim.steps,
        pool.current_num_threads()
    );
    println!(
        "{:<22} {:>10} {:>16} {:>14}",
        "estimators", "wall [s]", "agent-steps/s", "ns/agent-step"
    );
    let mut sets: Vec<(String, Vec<EstimatorEntry>)> = all
        .iter()
        .map(|e| {
            let kind = e.0["kind"].as_str().unwrap_or("?").to_string();
            (kind, vec![e.clone()])
        })
        .collect();
    sets.push(("none + rkf-ca + garkf".into(), all));
    for (label, set) in sets {
        let mut spec = base.clone();
        spec.estimators = set;
        time_row(pool, &spec, &format!("{label:<22}"), false)?;
    }
    println!("target (issue 10): none + rkf-ca + garkf ≥ 1.000e6 agent-steps/s on 2 cores");
    Ok(())
}

/// The cost model ([`edgekf::sim::cost`]) against this machine: each estimator of every shipped
/// filter scenario alone (its sweep and figures left out), the estimate beside the measured
/// simulation time, and their ratio (the estimate also counts writing the outputs, which is
/// not measured here).
fn cost_model(pool: &rayon::ThreadPool) -> Result<()> {
    let threads = pool.current_num_threads();
    println!(
        "\ncost model against this machine, {threads} thread(s): each estimator alone, no sweep"
    );
    println!(
        "{:<24} {:<16} {:>12} {:>12} {:>9}",
        "scenario", "estimator", "estimated", "measured", "est/meas"
    );
    let mut seen: Vec<&str> = Vec::new();
    let mut ratios: Vec<f64> = Vec::new();
    for e in registry::ENTRIES.iter().filter(|e| !e.is_slam()) {
        for (file, text) in e.companions.iter().copied().chain([(e.file, e.text)]) {
            if seen.contains(&file) {
                continue;
            }
            seen.push(file);
            let base = edgekf_io::spec_from_toml(text)?;
            let fw = registry::framework_of(file, &base)?;
            for est in &base.estimators {
                let mut spec = base.clone();
                spec.plots.clear();
                spec.sweep = None;
                spec.estimators = vec![est.clone()];
                let label = est
                    .0
                    .get("label")
                    .or_else(|| est.0.get("kind"))
                    .and_then(|v| v.as_str())
                    .unwrap_or("?");
                let sc = match Scenario::from_spec(&spec, fw.as_ref()) {
                    Ok(sc) => sc,
                    Err(err) => {
                        println!("{file:<24} {label:<16} not alone: {err}");
                        continue;
                    }
                };
                let estimated = edgekf::sim::cost(&sc, sc.runs(), threads).seconds;
                let t = Instant::now();
                pool.install(|| edgekf::sim::run(&sc, &edgekf::sim::Quiet))?;
                let measured = t.elapsed().as_secs_f64();
                ratios.push(estimated / measured);
                println!(
                    "{file:<24} {label:<16} {:>12} {:>12} {:>9.2}",
                    human_seconds(estimated),
                    human_seconds(measured),
                    estimated / measured
                );
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    if let (Some(lo), Some(hi)) = (ratios.first(), ratios.last()) {
        println!(
            "estimated / measured: {lo:.2} to {hi:.2}, median {:.2} ({} studies)",
            ratios[ratios.len() / 2],
            ratios.len()
        );
    }
    Ok(())
}

/// Runs `spec` once and prints a row: `label`, wall time, agent-steps per second and ns per
/// agent-step — counted per estimator when `per_estimator`, else once for the study.
fn time_row(
    pool: &rayon::ThreadPool,
    spec: &ScenarioSpec,
    label: &str,
    per_estimator: bool,
) -> Result<()> {
    let sc = edgekf::scenario::Scenario::from_spec(spec, None)?;
    let t = Instant::now();
    pool.install(|| edgekf::sim::run(&sc, &edgekf::sim::Quiet))?;
    let wall = t.elapsed().as_secs_f64();
    let estimators = if per_estimator {
        sc.estimators().len()
    } else {
        1
    };
    let agent_steps = (sc.framework().agents() * sc.runs() * sc.steps() * estimators) as f64;
    println!(
        "{label} {wall:>10.3} {:>16.3e} {:>14.1}",
        agent_steps / wall,
        wall / agent_steps * 1e9
    );
    Ok(())
}
