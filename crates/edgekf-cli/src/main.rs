//! The `edgekf` command-line program: a thin shell around the `edgekf` library.
//!
//! - `edgekf run SCENARIO --out DIR`: one scenario file (TOML, or a resolved `scenario.json`);
//! - `edgekf reproduce NAME… | all --out DIR`, `edgekf reproduce --list`: the papers' figures;
//! - `edgekf design`: stress design and rigidity checks of a framework;
//! - `edgekf fit-ar`: the AR input model of chapter 6 from trial runs;
//! - `edgekf bench`: closed-loop speed per estimator and the wall time of `reproduce`.

mod bench;
mod design;
mod io;
mod plot;
mod registry;
mod slam;
use edgekf_figure as figure;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use edgekf::scenario::Scenario;
use edgekf::sim::{self, Observer, Results};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

#[derive(Parser, Debug)]
#[command(
    name = "edgekf",
    version,
    about = "Edge-state Kalman filters for distributed formation control"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run one scenario file and write scenario.json, metrics.csv, paths.csv and its figures.
    Run {
        /// Scenario file: TOML, or a resolved scenario.json.
        scenario: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        over: Overrides,
    },
    /// Reproduce the papers' figures (shipped scenarios).
    Reproduce {
        /// Figure names (see --list), or `all`.
        names: Vec<String>,
        /// Output directory (one subdirectory per figure).
        #[arg(long, required_unless_present = "list")]
        out: Option<PathBuf>,
        /// Print the reproducible names, one a line.
        #[arg(long)]
        list: bool,
        #[command(flatten)]
        over: Overrides,
    },
    /// Design the stress (Laplacian weights) of a framework, check it, write framework.json and
    /// framework.png.
    Design(design::DesignArgs),
    /// Fit the AR(p) input model of `rkf-ar` / `rkf-commless` from trial runs (Yule–Walker).
    FitAr {
        /// Scenario file (its estimators are simulated; the fit uses one of them).
        scenario: PathBuf,
        /// AR order p.
        #[arg(long, default_value_t = 1)]
        order: usize,
        /// First step of the fitting window (the thesis's model is stationary, so skip the
        /// transient if you want a steady-state model).
        #[arg(long, default_value_t = 1)]
        from: usize,
        /// Label of the estimator whose closed loop generates the inputs (default: `rkf` if
        /// present, else the first).
        #[arg(long)]
        estimator: Option<String>,
        #[command(flatten)]
        over: Overrides,
    },
    /// Measure closed-loop speed per estimator and the wall time of reproducing the figures.
    Bench(bench::BenchArgs),
}

/// Overrides of the scenario file.
#[derive(Args, Debug, Clone, Default)]
pub struct Overrides {
    /// Monte Carlo runs.
    #[arg(long)]
    pub runs: Option<usize>,
    /// Time steps.
    #[arg(long)]
    pub steps: Option<usize>,
    /// Seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Report every this many steps.
    #[arg(long)]
    pub every: Option<usize>,
}

/// Progress on stderr; hidden when stderr is not a terminal.
struct Progress(ProgressBar);

impl Progress {
    fn new(total: u64, label: &str) -> Self {
        let pb = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        pb.set_style(
            ProgressStyle::with_template(
                "{prefix:>16} [{bar:40}] {percent:>3}% {elapsed}/{duration}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        pb.set_prefix(label.to_string());
        Self(pb)
    }
}

impl Observer for Progress {
    fn on_progress(&self, n: u64) {
        self.0.inc(n);
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("edgekf: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        if t == 0 {
            bail!("flag `--threads`: must be at least 1");
        }
        b = b.num_threads(t);
    }
    b.build().context("cannot start the worker threads")
}

fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run {
            scenario,
            out,
            over,
        } => {
            let text = fs::read_to_string(&scenario)
                .with_context(|| format!("cannot read {}", scenario.display()))?;
            let source = scenario.display().to_string();
            match io::kind_of(&text) {
                io::Kind::Slam => {
                    if over.runs.is_some()
                        || over.steps.is_some()
                        || over.seed.is_some()
                        || over.every.is_some()
                    {
                        bail!("{source}: --runs, --steps, --seed and --every apply to filter scenarios; a SLAM scenario sets its horizon and step in the file");
                    }
                    slam::run_text(&source, &text, &out)?;
                }
                io::Kind::Filters => {
                    let sc = io::load_scenario(&source, &text, scenario.parent())?;
                    let sc = apply_overrides(sc, &over).with_context(|| source.clone())?;
                    let pool = pool(over.threads)?;
                    let res = pool.install(|| simulate(&sc));
                    write_outputs(&out, &sc, &res, None)?;
                    eprintln!("wrote {}", out.display());
                }
            }
            Ok(())
        }
        Command::Reproduce {
            names,
            out,
            list,
            over,
        } => {
            if list {
                for e in registry::ENTRIES {
                    println!("{}\t{}", e.name, e.description);
                }
                return Ok(());
            }
            let out = out.expect("clap requires --out without --list");
            reproduce(&names, &out, &over)
        }
        Command::FitAr {
            scenario,
            order,
            from,
            estimator,
            over,
        } => fit_ar(&scenario, order, from, estimator.as_deref(), &over),
        Command::Bench(args) => bench::run(&args),
        Command::Design(args) => design::run(&args),
    }
}

fn fit_ar(
    path: &Path,
    order: usize,
    from: usize,
    label: Option<&str>,
    over: &Overrides,
) -> Result<()> {
    if order == 0 {
        bail!("flag `--order`: must be at least 1");
    }
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let source = path.display().to_string();
    let sc = io::load_scenario(&source, &text, path.parent())?;
    let sc = apply_overrides(sc, over).with_context(|| source.clone())?;
    if from == 0 || from + order > sc.steps {
        bail!(
            "flag `--from`: must lie in 1..={} for {} steps and order {order}",
            sc.steps - order,
            sc.steps
        );
    }
    let e = match label {
        Some(l) => sc
            .estimators
            .iter()
            .position(|d| d.label == l)
            .with_context(|| {
                format!("flag `--estimator`: `{l}` is not an estimator label of {source}")
            })?,
        None => sc
            .estimators
            .iter()
            .position(|d| d.label == "rkf")
            .unwrap_or(0),
    };
    let pool = pool(over.threads)?;
    let opt = sim::Options {
        input_lags: order,
        input_from: from,
    };
    let total = (sc.runs * sc.steps) as u64;
    let p = Progress::new(total, "fit-ar");
    let res = pool.install(|| sim::run_with(&sc, &p, opt));
    p.0.finish_and_clear();
    let acov = &res.input_acov[e];
    let mut coeffs = vec![vec![0.0; acov.len()]; order];
    let mut noise = Vec::new();
    println!(
        "# AR({order}) fit (Yule–Walker) of the inputs u_k of every agent in the closed loop of `{}`,",
        sc.estimators[e].label
    );
    println!(
        "# {} runs × {} agents, steps {from}..={} of {}, seed {}",
        sc.runs,
        sc.framework.agents(),
        sc.steps,
        source,
        sc.seed
    );
    for (d, r) in acov.iter().enumerate() {
        let (a, v) = edgekf::estimate::ar::yule_walker(r).with_context(|| {
            format!("coordinate {d}: the inputs are identically zero; nothing to fit")
        })?;
        let rho: Vec<String> = r.iter().map(|x| format!("{:.4}", x / r[0])).collect();
        println!(
            "# coordinate {d}: r(0) = {:.6e} (m/s)², autocorrelation [{}]",
            r[0],
            rho.join(", ")
        );
        for (l, c) in a.iter().enumerate() {
            coeffs[l][d] = *c;
        }
        noise.push(v);
    }
    println!("[comm.ar]");
    let rows: Vec<String> = coeffs
        .iter()
        .map(|c| {
            format!(
                "[{}]",
                c.iter()
                    .map(|v| format!("{v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect();
    println!("coeffs = [{}]", rows.join(", "));
    println!(
        "noise_var = [{}]",
        noise
            .iter()
            .map(|v| format!("{v}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

fn apply_overrides(sc: Scenario, over: &Overrides) -> Result<Scenario> {
    Ok(sc.with_overrides(over.runs, over.steps, over.seed, over.every)?)
}

/// Runs a scenario with a progress bar.
pub fn simulate(sc: &Scenario) -> Results {
    let total = (sc.runs * sc.steps) as u64;
    let p = Progress::new(total, &sc.name);
    let res = sim::run(sc, &p);
    p.0.finish_and_clear();
    res
}

/// Writes scenario.json, metrics.csv, paths.csv and the figures (all of them, or `plots`).
fn write_outputs(out: &Path, sc: &Scenario, res: &Results, plots: Option<&[&str]>) -> Result<()> {
    fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json =
        serde_json::to_string_pretty(&sc.to_resolved()).context("cannot serialise the scenario")?;
    io::write_atomic(out, "scenario.json", json.as_bytes())?;
    io::write_atomic(out, "metrics.csv", io::metrics_csv(res).as_bytes())?;
    io::write_atomic(
        out,
        "paths.csv",
        io::paths_csv(res, sc.framework.dim(), sc.framework.agents()).as_bytes(),
    )?;
    for p in &sc.plots {
        if plots.is_none_or(|want| want.contains(&p.file.as_str())) {
            plot::render(out, p, sc, res)?;
        }
    }
    Ok(())
}

fn reproduce(names: &[String], out: &Path, over: &Overrides) -> Result<()> {
    if names.is_empty() {
        bail!("name the figures to reproduce (see `edgekf reproduce --list`), or `all`");
    }
    let mut entries: Vec<&registry::Entry> = Vec::new();
    for n in names {
        if n == "all" {
            entries.extend(registry::ENTRIES.iter());
        } else {
            let e = registry::find(n).with_context(|| {
                format!("unknown figure `{n}`; `edgekf reproduce --list` prints the names")
            })?;
            entries.push(e);
        }
    }
    let pool = pool(over.threads)?;
    let (slams, entries): (Vec<&registry::Entry>, Vec<&registry::Entry>) = entries
        .into_iter()
        .partition(|e| matches!(io::kind_of(e.text), io::Kind::Slam));
    // Check every scenario before running any, so a bad flag fails at once.
    let mut files: Vec<(&str, Scenario)> = Vec::new();
    for e in &entries {
        if files.iter().any(|(f, _)| *f == e.file) {
            continue;
        }
        let sc = io::load_scenario(e.file, e.text, None)?;
        files.push((e.file, apply_overrides(sc, over)?));
    }
    let start = Instant::now();
    for (file, sc) in &files {
        let t = Instant::now();
        let res = pool.install(|| simulate(sc));
        let sim_time = t.elapsed();
        for e in entries.iter().filter(|e| e.file == *file) {
            let dir = out.join(e.name);
            write_outputs(&dir, sc, &res, Some(e.plots))?;
            eprintln!("{:<16} {}", e.name, dir.display());
        }
        eprintln!(
            "  ({file}: {} runs × {} steps simulated in {:.2?})",
            sc.runs, sc.steps, sim_time
        );
    }
    for e in &slams {
        let dir = out.join(e.name);
        slam::run_text(e.file, e.text, &dir)?;
        eprintln!("{:<16} {}", e.name, dir.display());
    }
    eprintln!(
        "reproduced {} figure(s) in {:.2?}",
        entries.len() + slams.len(),
        start.elapsed()
    );
    Ok(())
}
