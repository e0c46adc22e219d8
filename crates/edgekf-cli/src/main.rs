//! The `edgekf` command-line program: a thin shell around the `edgekf` library.
//!
//! - `edgekf run SCENARIO --out DIR`: one scenario file (TOML, or a resolved `scenario.json`),
//!   optionally one shard of its runs (`--shard I/K`);
//! - `edgekf merge D1 … DK --out DIR`: the shards' partial results into the study's outputs;
//! - `edgekf reproduce NAME… | all --out DIR`, `edgekf reproduce --list`: the papers' figures;
//! - `edgekf design`: stress design and rigidity checks of a framework;
//! - `edgekf fit-ar`: the AR input model of chapter 6 from trial runs;
//! - `edgekf bench`: closed-loop speed per estimator and the wall time of `reproduce`;
//! - `edgekf report DIR`: a self-contained HTML page per study (and an index for a `reproduce`
//!   output root);
//! - `edgekf claims`: the papers' claims checked on the reproductions (`edgekf-claims`);
//! - `edgekf agent`, `edgekf world`, `edgekf swarm` (feature `swarm`): the agents as processes
//!   over Zenoh (`edgekf-swarm`).
//!
//! Results go to files (written atomically, only after the study succeeded) and a short summary
//! to stdout; logs and progress go to stderr.

mod bench;
mod claims;
mod design;
mod interrupt;
mod io;
mod player;
mod report;
mod slam;
mod summary;
#[cfg(feature = "swarm")]
mod swarm;
use edgekf_figure as figure;
use edgekf_figure::{plot, plot_garkf};

use std::fs;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use edgekf::scenario::Scenario;
use edgekf::sim::{self, Observer, Outcome, Results};
use edgekf_io::outdir::{self, Hint, StudyId};
use edgekf_io::reproductions as registry;
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
    /// Run one scenario file and write scenario.json, metrics.csv, paths.csv, status.csv,
    /// frames.json (the report page's player, when the study has frames), provenance.json and
    /// its figures; print the steady-state summary.
    Run {
        /// Scenario file: TOML, or a resolved scenario.json.
        scenario: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Run only shard I of K (contiguous run ranges, the same per-run seeds) and write
        /// partial results for `edgekf merge`.
        #[arg(long, value_parser = parse_shard)]
        shard: Option<(usize, usize)>,
        /// Replace the output directory's contents when it holds files of another study (outputs
        /// never mix: without it such a directory is refused; a re-run of the same study replaces
        /// its files). The old files go once the new ones are in place: an interrupted run
        /// leaves them.
        #[arg(long)]
        force: bool,
        #[command(flatten)]
        over: Overrides,
    },
    /// Merge the partial results of `run --shard I/K` into the outputs of the whole study
    /// (metrics.csv byte-identical to the unsharded run's).
    Merge {
        /// The shards' output directories, in any order.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
        /// Replace the output directory's contents when it holds files of another study (once the
        /// new files are in place: an interrupted run leaves the old ones).
        #[arg(long)]
        force: bool,
    },
    /// Reproduce the papers' figures (shipped scenarios).
    Reproduce {
        /// Figure names (see --list), or `all`.
        names: Vec<String>,
        /// Output directory (one subdirectory per simulation, its figures beside its data).
        #[arg(long, required_unless_present = "list")]
        out: Option<PathBuf>,
        /// Print the reproducible names, one a line.
        #[arg(long)]
        list: bool,
        /// Also write a self-contained HTML page per simulation (`report.html`) and
        /// `index.html` (see `edgekf report`).
        #[arg(long)]
        report: bool,
        /// Replace each simulation's directory's contents when it holds files of another study
        /// (once its new files are in place).
        #[arg(long)]
        force: bool,
        #[command(flatten)]
        over: Overrides,
    },
    /// Write a self-contained HTML page (`report.html`: figures, steady-state table, claims,
    /// resolved scenario, provenance) for a study's output directory, or one per simulation and
    /// `index.html` for a `reproduce` output root.
    Report {
        /// A study's output directory, or a `reproduce` output root.
        dir: PathBuf,
    },
    /// Design the stress (Laplacian weights) of a framework, check it, write framework.json and
    /// framework.png.
    Design(design::DesignArgs),
    /// Fit the AR(p) input model of `rkf-ar` / `rkf-commless` from trial runs (Yule–Walker).
    FitAr {
        /// Scenario file (its estimators are simulated; the fit uses one of them).
        scenario: PathBuf,
        /// AR order p.
        #[arg(long, default_value_t = 1, allow_negative_numbers = true, value_parser = positive)]
        order: usize,
        /// First step of the fitting window (skip the transient for a steady-state model).
        #[arg(long, default_value_t = 1, allow_negative_numbers = true, value_parser = positive)]
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
    /// Check the papers' claims on the reproductions: a table (or JSON) with each claim, the
    /// paper's value, ours ± its standard error, and the verdict.
    Claims(claims::ClaimsArgs),
    /// One agent as a process over Zenoh (feature `swarm`): its measurements from the world,
    /// its neighbours' messages over the mesh, its control input back to the world.
    #[cfg(feature = "swarm")]
    Agent(swarm::AgentArgs),
    /// The simulated world as a process over Zenoh (feature `swarm`): true positions, the
    /// agents' noisy measurements, their inputs integrated; writes the files of `edgekf run`
    /// and network.csv.
    #[cfg(feature = "swarm")]
    World(swarm::WorldArgs),
    /// The world and one process per agent on this machine (feature `swarm`), with real
    /// departures (`--kill AGENT@SECONDS`).
    #[cfg(feature = "swarm")]
    Swarm(swarm::SwarmArgs),
}

/// `--max-hours` by default: a study (or a design) estimated to take longer is refused before it
/// starts (the CRKF at 1,000 agents, 2,000 steps: about 4.4 h).
pub const DEFAULT_MAX_HOURS: f64 = 1.0;

/// Memory a study or design may take, as a share of the available memory (`MemAvailable`).
pub const MEMORY_SHARE: f64 = 0.8;

/// Exit code when an estimator diverged (1: an error, 2: a usage error).
const DIVERGED: u8 = 3;

/// A whole number ≥ 1, with a message naming the problem.
fn positive(s: &str) -> Result<usize, String> {
    match s.trim().parse::<i128>() {
        Ok(v) if v >= 1 && v <= usize::MAX as i128 => Ok(v as usize),
        Ok(v) => Err(format!("must be a whole number ≥ 1, got {v}")),
        Err(_) => Err(format!("must be a whole number ≥ 1, got `{s}`")),
    }
}

/// A seed: a whole number ≥ 0.
fn seed(s: &str) -> Result<u64, String> {
    s.trim()
        .parse::<u64>()
        .map_err(|_| format!("must be a whole number in 0..=2^64−1, got `{s}`"))
}

/// A positive number of hours.
fn hours(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("must be a number of hours > 0, got `{s}`")),
    }
}

/// `I/K` with 1 ≤ I ≤ K.
fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (i, k) = s
        .split_once('/')
        .ok_or_else(|| format!("must be I/K (shard I of K), got `{s}`"))?;
    let (i, k) = (positive(i)?, positive(k)?);
    if i > k {
        return Err(format!("shard {i} of {k}: I must lie in 1..={k}"));
    }
    Ok((i, k))
}

/// Overrides of the scenario file.
#[derive(Args, Debug, Clone)]
pub struct Overrides {
    /// Monte Carlo runs.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub runs: Option<usize>,
    /// Time steps.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub steps: Option<usize>,
    /// Seed.
    #[arg(long, allow_negative_numbers = true, value_parser = seed)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub threads: Option<usize>,
    /// Report every this many steps.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub every: Option<usize>,
    /// Run a closed loop past its stability bound, and exit with success even when an estimator
    /// diverges (to show the divergence).
    #[arg(long)]
    pub allow_divergence: bool,
    /// Refuse a study estimated to take longer than this many hours (the estimate is checked
    /// before anything runs; a study that needs more than 80 % of the available memory is
    /// refused too).
    #[arg(long, default_value_t = DEFAULT_MAX_HOURS, value_parser = hours)]
    pub max_hours: f64,
    /// Print the summary as JSON (for scripts) instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl Default for Overrides {
    fn default() -> Self {
        Self {
            runs: None,
            steps: None,
            seed: None,
            threads: None,
            every: None,
            allow_divergence: false,
            max_hours: DEFAULT_MAX_HOURS,
            json: false,
        }
    }
}

/// Why a SLAM study is not sized by the flags of a filter study.
const SLAM_SIZES: &str = "--runs, --steps, --seed and --every apply to filter scenarios; a SLAM study sets its horizon and step in its file";

impl Overrides {
    /// Whether a flag that sizes or seeds a filter study (`--runs`, `--steps`, `--seed`,
    /// `--every`) is given: a SLAM study takes none of them.
    fn sizes_filter(&self) -> bool {
        self.runs.is_some() || self.steps.is_some() || self.seed.is_some() || self.every.is_some()
    }
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
    interrupt::install();
    #[cfg(not(feature = "swarm"))]
    if let Some(cmd) = std::env::args()
        .nth(1)
        .filter(|a| matches!(a.as_str(), "agent" | "world" | "swarm"))
    {
        // Not clap's "unrecognized subcommand": the command exists, this build lacks it.
        eprintln!(
            "edgekf: error: `edgekf {cmd}` runs the agents over Zenoh, which this build leaves out \
             (feature `swarm`); build it with `cargo build --release -p edgekf-cli --features swarm`"
        );
        return ExitCode::from(2);
    }
    let cli = Cli::parse();
    let code = match dispatch(cli) {
        Ok(code) => code,
        Err(e) => {
            // An error that a Ctrl-C caused is not reported as one: the interrupt's line is.
            interrupt::settle();
            eprintln!("edgekf: error: {e:#}");
            ExitCode::FAILURE
        }
    };
    interrupt::settle();
    code
}

fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        b = b.num_threads(t);
    }
    b.build().context("cannot start the worker threads")
}

fn dispatch(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Run {
            scenario,
            out,
            shard,
            force,
            over,
        } => run(&scenario, &out, shard, force, &over),
        Command::Merge {
            parts,
            out,
            json,
            force,
        } => merge(&parts, &out, json, force),
        Command::Reproduce {
            names,
            out,
            list,
            report,
            force,
            over,
        } => {
            if list {
                for e in registry::ENTRIES {
                    println!("{}\t{}", e.name, e.description);
                }
                return Ok(ExitCode::SUCCESS);
            }
            let out = out.context("flag `--out`: required without `--list`")?;
            reproduce(&names, &out, &over, report, force)
        }
        Command::Report { dir } => {
            for p in report::run(&dir)? {
                eprintln!("wrote {}", p.display());
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::FitAr {
            scenario,
            order,
            from,
            estimator,
            over,
        } => {
            fit_ar(&scenario, order, from, estimator.as_deref(), &over).map(|()| ExitCode::SUCCESS)
        }
        Command::Bench(args) => bench::run(&args).map(|()| ExitCode::SUCCESS),
        Command::Design(args) => design::run(&args).map(|()| ExitCode::SUCCESS),
        Command::Claims(args) => claims::run(&args).map(|()| ExitCode::SUCCESS),
        #[cfg(feature = "swarm")]
        Command::Agent(args) => swarm::agent(&args),
        #[cfg(feature = "swarm")]
        Command::World(args) => swarm::world(&args),
        #[cfg(feature = "swarm")]
        Command::Swarm(args) => swarm::swarm(&args),
    }
}

/// `edgekf run`: a SLAM scenario or a filter study (all its runs, a shard of them, or a sweep).
fn run(
    scenario: &Path,
    out: &Path,
    shard: Option<(usize, usize)>,
    force: bool,
    over: &Overrides,
) -> Result<ExitCode> {
    let text = fs::read_to_string(scenario)
        .with_context(|| format!("cannot read {}", scenario.display()))?;
    let source = scenario.display().to_string();
    if let io::Kind::Slam = io::kind_of(&text) {
        return run_slam(&source, &text, out, shard.is_some(), force, over);
    }
    let sc = load(&source, &text, scenario.parent(), over)?;
    let pool = pool(over.threads)?;
    let range = shard_runs(&sc, shard)?;
    check_cost(&sc, range.len(), pool.current_num_threads(), over)?;
    let id = if shard.is_some() {
        StudyId::new("shard", sc.name())
    } else {
        StudyId::study(sc.name())
    };
    let prep = outdir::prepare(out, &id, force, Hint::CLI)?;
    if sc.sweep().is_some() {
        if shard.is_some() {
            bail!("flag `--shard`: a scenario with a [sweep] is not sharded; split its `values` over several scenario files instead");
        }
        let sw = pool.install(|| simulate_sweep(&sc))?;
        let mut st = interrupt::stage(out)?;
        let extra = plot_garkf::Extra {
            sweep: Some(&sw),
            ..Default::default()
        };
        pool.install(|| stage_outputs(&mut st, &sc, &sw.base, None, &extra))?;
        commit(st, prep, &id)?;
        eprintln!(
            "wrote {} (a sweep of {} values)",
            out.display(),
            sw.points.len()
        );
        return Ok(report(&sc, &sw.base, over));
    }
    let res = pool.install(|| simulate(&sc, range))?;
    let mut st = interrupt::stage(out)?;
    if let Some(s) = shard {
        stage_scenario(&mut st, &sc)?;
        io::write_shard(&mut st, &res, s)?;
        commit(st, prep, &id)?;
        eprintln!(
            "wrote shard {}/{} (runs {}..{}) to {}",
            s.0,
            s.1,
            res.runs.start,
            res.runs.end,
            out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    pool.install(|| stage_outputs(&mut st, &sc, &res, None, &plot_garkf::Extra::default()))?;
    commit(st, prep, &id)?;
    eprintln!("wrote {}", out.display());
    Ok(report(&sc, &res, over))
}

/// `edgekf run` of a SLAM scenario (`source`'s `text`): the filter study's flags are refused.
fn run_slam(
    source: &str,
    text: &str,
    out: &Path,
    shard: bool,
    force: bool,
    over: &Overrides,
) -> Result<ExitCode> {
    if over.sizes_filter() || shard {
        bail!("{source}: {SLAM_SIZES}; --shard, too, splits filter studies only");
    }
    let id = StudyId::new("slam", &slam::study_name(source, text)?);
    let prep = outdir::prepare(out, &id, force, Hint::CLI)?;
    let st = slam::run_text(source, text, out, over.json)?;
    commit(st, prep, &id)?;
    Ok(ExitCode::SUCCESS)
}

/// The runs of `--shard i/k` (all of them without it), or why the flag does not fit.
fn shard_runs(sc: &Scenario, shard: Option<(usize, usize)>) -> Result<std::ops::Range<usize>> {
    Ok(match shard {
        Some((_, k)) if k > sc.runs() => bail!(
            "flag `--shard`: {k} shards for {} runs leaves some shards empty; use at most {} shards",
            sc.runs(),
            sc.runs()
        ),
        Some((i, k)) => sim::shard_range(sc.runs(), i, k),
        None => 0..sc.runs(),
    })
}

/// Prints the summary; the exit code says whether every estimator completed.
fn report(sc: &Scenario, res: &Results, over: &Overrides) -> ExitCode {
    let s = summary::summarise(sc.name(), res);
    if over.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&s).unwrap_or_else(|_| "{}".into())
        );
    } else {
        print!("{}", summary::table(&s));
    }
    let diverged: Vec<&str> = res
        .estimators
        .iter()
        .filter(|e| matches!(e.outcome, Outcome::Diverged { .. }))
        .map(|e| e.label.as_str())
        .collect();
    if diverged.is_empty() || sc.allow_divergence() {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "edgekf: error: {} diverged (see status.csv); pass --allow-divergence (or set `sim.allow_divergence = true` in the scenario) to accept it",
            diverged.join(", ")
        );
        ExitCode::from(DIVERGED)
    }
}

/// Available memory from `/proc/meminfo` (Linux), in bytes.
pub fn available_memory() -> Option<f64> {
    let text = fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Refuses a study that cannot fit in memory or would take longer than `--max-hours`, and
/// announces a long one.
fn check_cost(sc: &Scenario, runs: usize, threads: usize, over: &Overrides) -> Result<()> {
    let c = sim::cost(sc, runs, threads);
    if let Some(avail) = available_memory() {
        if c.bytes > MEMORY_SHARE * avail {
            bail!(
                "{}: this study needs about {} of memory ({} runs, {} reported steps of {} estimators) but {} is available (the limit is 80 % of it); lower `runs` (`--runs`), raise `every` (`--every`), or shard it (`--shard I/K`)",
                sc.name(),
                sim::cost::human_bytes(c.bytes),
                runs,
                sc.report_count(),
                sc.estimators().len(),
                sim::cost::human_bytes(avail)
            );
        }
    }
    if c.seconds > over.max_hours * 3600.0 {
        bail!(
            "{}: this study would take about {} on {threads} thread(s) ({} of it in computations shared by all runs, such as a centralised covariance); the limit is {} h (`--max-hours`, default {DEFAULT_MAX_HOURS} h; raise it to run it anyway). Lower `steps`, `runs` or the network size, drop the costliest estimator, or shard it",
            sc.name(),
            sim::cost::human_seconds(c.seconds),
            sim::cost::human_seconds(c.shared_seconds),
            over.max_hours
        );
    }
    if c.seconds > 60.0 {
        eprintln!(
            "{}: estimated {} on {threads} thread(s), {} of memory",
            sc.name(),
            sim::cost::human_seconds(c.seconds),
            sim::cost::human_bytes(c.bytes)
        );
    }
    Ok(())
}

fn fit_ar(
    path: &Path,
    order: usize,
    from: usize,
    label: Option<&str>,
    over: &Overrides,
) -> Result<()> {
    if over.every.is_some() {
        bail!("flag `--every`: fit-ar reports nothing per step (it fits the inputs of steps --from on); leave it out");
    }
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let source = path.display().to_string();
    let sc = load(&source, &text, path.parent(), over)?;
    // The fit needs the window's first step plus `order` lags inside the run.
    if order >= sc.steps() {
        bail!(
            "flag `--order`: must lie in 1..={} for {} steps (the fitting window needs at least one step after the {order} lags)",
            sc.steps().saturating_sub(1).max(1),
            sc.steps()
        );
    }
    if from + order > sc.steps() {
        bail!(
            "flag `--from`: must lie in 1..={} for {} steps and order {order}",
            sc.steps() - order,
            sc.steps()
        );
    }
    let e = match label {
        Some(l) => sc
            .estimators()
            .iter()
            .position(|d| d.label() == l)
            .with_context(|| {
                format!("flag `--estimator`: `{l}` is not an estimator label of {source}")
            })?,
        None => sc
            .estimators()
            .iter()
            .position(|d| d.label() == "rkf")
            .unwrap_or(0),
    };
    let pool = pool(over.threads)?;
    check_cost(&sc, sc.runs(), pool.current_num_threads(), over)?;
    let opt = sim::Options {
        input_lags: order,
        input_from: from,
        ..sim::Options::default()
    };
    let total = (sc.runs() * sc.steps()) as u64;
    let p = Progress::new(total, "fit-ar");
    let res = pool.install(|| sim::run_with(&sc, &p, opt))?;
    p.0.finish_and_clear();
    let fit = ArFit::of(&res.input_acov[e])?;
    let label = sc.estimators()[e].label();
    fit.print(&sc, label, (order, from), &source, over.json)
}

/// The Yule–Walker fit of each coordinate's input autocovariances (lags 0..=order): what
/// `fit-ar` prints, as the `[comm.ar]` table of a scenario file or as JSON.
struct ArFit {
    /// `r(0)` per coordinate, (m/s)².
    r0: Vec<f64>,
    /// The autocorrelations `r(l) / r(0)`, l = 0..=order, per coordinate.
    rho: Vec<Vec<f64>>,
    /// `coeffs[l][d]`: coordinate d's coefficient of lag l + 1 (the `[comm.ar]` key).
    coeffs: Vec<Vec<f64>>,
    /// The innovations' variance per coordinate (the `[comm.ar]` key).
    noise_var: Vec<f64>,
}

impl ArFit {
    /// The fit of `acov[d]`, each coordinate's autocovariances at lags 0..=order.
    fn of(acov: &[Vec<f64>]) -> Result<Self> {
        let order = acov.first().map_or(0, |r| r.len().saturating_sub(1));
        let mut fit = ArFit {
            r0: Vec::new(),
            rho: Vec::new(),
            coeffs: vec![vec![0.0; acov.len()]; order],
            noise_var: Vec::new(),
        };
        for (d, r) in acov.iter().enumerate() {
            let (a, v) = edgekf::estimate::ar::yule_walker(r).with_context(|| {
                format!("coordinate {d}: the inputs are identically zero; nothing to fit")
            })?;
            fit.r0.push(r[0]);
            fit.rho.push(r.iter().map(|x| x / r[0]).collect());
            for (l, c) in a.iter().enumerate() {
                fit.coeffs[l][d] = *c;
            }
            fit.noise_var.push(v);
        }
        Ok(fit)
    }

    /// Prints the fit of the inputs of the loop `label` of `sc` (fitted over steps `from` on
    /// with `order` lags): as JSON, or as comments on where it comes from and the table.
    fn print(
        &self,
        sc: &Scenario,
        label: &str,
        (order, from): (usize, usize),
        source: &str,
        json: bool,
    ) -> Result<()> {
        let agents = sc.framework().agents();
        if json {
            let v = serde_json::json!({
                "estimator": label, "order": order, "from": from, "steps": sc.steps(),
                "runs": sc.runs(), "agents": agents, "seed": sc.seed(), "source": source,
                "r0": self.r0, "autocorrelation": self.rho,
                "coeffs": self.coeffs, "noise_var": self.noise_var,
            });
            println!("{}", serde_json::to_string_pretty(&v)?);
            return Ok(());
        }
        println!(
            "# AR({order}) fit (Yule–Walker) of the inputs u_k of every agent in the closed loop of `{label}`,"
        );
        println!(
            "# {} runs × {agents} agents, steps {from}..={} of {source}, seed {}",
            sc.runs(),
            sc.steps(),
            sc.seed()
        );
        self.print_toml();
        Ok(())
    }

    /// The autocorrelations as comments, then the `[comm.ar]` table.
    fn print_toml(&self) {
        for (d, (r0, rho)) in self.r0.iter().zip(&self.rho).enumerate() {
            let rho: Vec<String> = rho.iter().map(|x| format!("{x:.4}")).collect();
            println!(
                "# coordinate {d}: r(0) = {r0:.6e} (m/s)², autocorrelation [{}]",
                rho.join(", ")
            );
        }
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let rows: Vec<String> = self
            .coeffs
            .iter()
            .map(|c| format!("[{}]", list(c)))
            .collect();
        println!("[comm.ar]");
        println!("coeffs = [{}]", rows.join(", "));
        println!("noise_var = [{}]", list(&self.noise_var));
    }
}

/// Loads a filter scenario and applies the overrides. `--allow-divergence` sets the scenario's
/// `allow_divergence` before it is checked, so it lifts the load-time stability refusal exactly
/// as the key does; without it, a refusal that the key would lift names the flag too.
fn load(source: &str, text: &str, base: Option<&Path>, over: &Overrides) -> Result<Scenario> {
    load_with(source, text, over, &|t| {
        Ok(io::load_scenario(source, t, base)?)
    })
}

/// [`load`] with the scenario text parsed and checked by `parse`.
fn load_with(
    source: &str,
    text: &str,
    over: &Overrides,
    parse: &dyn Fn(&str) -> Result<Scenario>,
) -> Result<Scenario> {
    let sc = if over.allow_divergence {
        parse(&io::allowing_divergence(text))?
    } else {
        parse(text).map_err(|e| {
            let msg = format!("{e:#}");
            if msg.contains("allow_divergence") {
                anyhow::anyhow!("{msg} (on the command line: --allow-divergence)")
            } else {
                e
            }
        })?
    };
    apply_overrides(sc, over).with_context(|| source.to_string())
}

fn apply_overrides(mut sc: Scenario, over: &Overrides) -> Result<Scenario> {
    if over.allow_divergence {
        sc = sc.with_allow_divergence(true)?;
    }
    if over.runs.is_some() || over.steps.is_some() || over.every.is_some() {
        sc = sc.with_size(over.runs, over.steps, over.every)?;
    }
    if let Some(s) = over.seed {
        sc = sc.with_seed(s);
    }
    for w in sc.warnings() {
        eprintln!("warning: {}: {w}", sc.name());
    }
    Ok(sc)
}

/// Runs the runs `range` of a scenario with a progress bar.
pub fn simulate(sc: &Scenario, range: std::ops::Range<usize>) -> Result<Results> {
    let total = (range.len() * sc.steps()) as u64;
    let p = Progress::new(total, sc.name());
    // A few runs frame by frame for the report page's player, within its byte budget.
    let res = sim::run_range(sc, range, &p, edgekf_io::frames::frame_options(sc));
    p.0.finish_and_clear();
    Ok(res?)
}

/// The environment variable by which `edgekf swarm` tells the world it starts the command the
/// user typed (a JSON list of strings), for the study's `provenance.json`.
pub(crate) const INVOKED_AS: &str = "EDGEKF_INVOKED_AS";

/// The command line a study's `provenance.json` records: this process's, or for the world of a
/// swarm, the `edgekf swarm` command that started it ([`INVOKED_AS`]).
fn command_line() -> Vec<String> {
    std::env::var(INVOKED_AS)
        .ok()
        .and_then(|v| serde_json::from_str(&v).ok())
        .unwrap_or_else(|| std::env::args().collect())
}

/// Stages `provenance.json` (this process's command line, the study, and the list of files
/// staged), moves every staged file into place, and removes what the previous run of the same
/// study left that this one did not write again — as one step that Ctrl-C does not cut.
fn commit(mut st: io::Staged, prep: outdir::Prepared, id: &StudyId) -> Result<()> {
    let mut names = st.names();
    let prov = outdir::provenance_json(command_line(), id, &names);
    st.write("provenance.json", prov.as_bytes())?;
    names.push("provenance.json".into());
    let dir = prep.dir().to_path_buf();
    interrupt::critical(&dir, || {
        st.commit()?;
        prep.finish(&names)?;
        Ok(())
    })
}

/// Runs a sweep ([`sim::sweep`]) with a progress bar.
fn simulate_sweep(sc: &Scenario) -> Result<sim::sweep::SweepResults> {
    let p = Progress::new(sim::sweep::total_run_steps(sc), sc.name());
    // The scenario as written frame by frame, as a study without a sweep.
    let frames = edgekf_io::frames::frame_options(sc);
    let res = sim::sweep::run_with(sc, &p, frames);
    p.0.finish_and_clear();
    Ok(res?)
}

fn stage_scenario(st: &mut io::Staged, sc: &Scenario) -> Result<()> {
    st.write("scenario.json", edgekf_io::scenario_json(sc)?.as_bytes())?;
    Ok(())
}

/// Stages scenario.json, metrics.csv, paths.csv, status.csv, a sweep's summary.csv and
/// sweep_metrics.csv, and the figures (all, or `plots`); [`commit`] adds provenance.json.
fn stage_outputs(
    st: &mut io::Staged,
    sc: &Scenario,
    res: &Results,
    plots: Option<&[&str]>,
    extra: &plot_garkf::Extra<'_>,
) -> Result<()> {
    if let Some(sw) = extra.sweep {
        st.write("summary.csv", io::summary_csv(sw).as_bytes())?;
        st.write(
            "sweep_metrics.csv",
            io::sweep_metrics_csv(sw, sc.sweep().and_then(|s| s.series.as_deref())).as_bytes(),
        )?;
    }
    edgekf_io::stage_tables(st, sc, res)?;
    Ok(figure::render_study(
        |file| st.path(file),
        sc,
        res,
        plots,
        extra,
    )?)
}

fn merge(parts: &[PathBuf], out: &Path, json: bool, force: bool) -> Result<ExitCode> {
    let mut scenario_text: Option<String> = None;
    let mut results = Vec::new();
    for dir in parts {
        let sp = dir.join("scenario.json");
        let text =
            fs::read_to_string(&sp).with_context(|| format!("cannot read {}", sp.display()))?;
        match &scenario_text {
            None => scenario_text = Some(text),
            Some(t) if *t != text => bail!(
                "{}: the shards are of different scenarios (scenario.json differs from {})",
                sp.display(),
                parts[0].join("scenario.json").display()
            ),
            Some(_) => {}
        }
        results.push(io::read_shard(dir)?);
    }
    let text = scenario_text.context("no shard directories given")?;
    let source = parts[0].join("scenario.json").display().to_string();
    let sc = io::load_scenario(&source, &text, None)?;
    let res = Results::merge(results).context("cannot merge the shards")?;
    if res.total_runs != sc.runs() {
        bail!(
            "the shards hold {} runs but the scenario has {}",
            res.total_runs,
            sc.runs()
        );
    }
    let id = StudyId::study(sc.name());
    let prep = outdir::prepare(out, &id, force, Hint::CLI)?;
    let mut st = interrupt::stage(out)?;
    stage_outputs(&mut st, &sc, &res, None, &plot_garkf::Extra::default())?;
    commit(st, prep, &id)?;
    eprintln!("merged {} shard(s) into {}", parts.len(), out.display());
    let over = Overrides {
        json,
        ..Overrides::default()
    };
    Ok(report(&sc, &res, &over))
}

/// The simulation directory of a scenario file (`eusipco.toml` → `eusipco`).
fn sim_dir(file: &str) -> &str {
    file.strip_suffix(".toml").unwrap_or(file)
}

fn reproduce(
    names: &[String],
    out: &Path,
    over: &Overrides,
    html: bool,
    force: bool,
) -> Result<ExitCode> {
    let entries = select_entries(names)?;
    let pool = pool(over.threads)?;
    let (slams, entries): (Vec<&registry::Entry>, Vec<&registry::Entry>) = entries
        .into_iter()
        .partition(|e| matches!(io::kind_of(e.text), io::Kind::Slam));
    check_slam_sizes(&slams, entries.is_empty(), over)?;
    let files = check_reproductions(&entries, over, pool.current_num_threads())?;
    let (mut prepared, mut slam_prepared) = prepare_reproductions(out, force, &files, &slams)?;
    let start = Instant::now();
    let mut code = ExitCode::SUCCESS;
    let mut pages: Vec<PathBuf> = Vec::new();
    let mut done: Vec<(&str, Option<sim::sweep::SweepResults>)> = Vec::new();
    for (k, (file, sc)) in files.iter().enumerate() {
        let t = Instant::now();
        let (res, sweep) = if sc.sweep().is_some() {
            let sw = pool.install(|| simulate_sweep(sc))?;
            (sw.base.clone(), Some(sw))
        } else {
            (pool.install(|| simulate(sc, 0..sc.runs()))?, None)
        };
        let sim_time = t.elapsed();
        let dir = out.join(sim_dir(file));
        let mine: Vec<&registry::Entry> = entries
            .iter()
            .copied()
            .filter(|e| e.file == *file)
            .collect();
        let plots: Vec<&str> = mine.iter().flat_map(|e| e.plots.iter().copied()).collect();
        let extra = plot_garkf::Extra {
            sweep: sweep.as_ref(),
            companions: companions(&mine, &files, &done),
        };
        let mut st = interrupt::stage(&dir)?;
        pool.install(|| stage_outputs(&mut st, sc, &res, Some(&plots), &extra))?;
        let prep = prepared[k]
            .take()
            .context("each simulation is prepared once")?;
        commit(st, prep, &StudyId::study(sc.name()))?;
        let threads = pool.current_num_threads();
        print_reproduced(&mine, &dir, (file, sc, threads), sweep.as_ref(), sim_time);
        if report(sc, &res, over) != ExitCode::SUCCESS {
            code = ExitCode::from(DIVERGED);
        }
        if html {
            pages.push(interrupt::critical(&dir.join("report.html"), || {
                report::write_page(&dir)
            })?);
        }
        done.push((file, sweep));
    }
    reproduce_slams(
        &slams,
        &mut slam_prepared,
        out,
        over,
        html.then_some(&mut pages),
    )?;
    if html {
        let index =
            interrupt::critical(&out.join("index.html"), || report::write_index(out, &pages))?;
        for p in pages.iter().chain(std::iter::once(&index)) {
            eprintln!("wrote {}", p.display());
        }
    }
    eprintln!(
        "reproduced {} figure(s) in {:.2?}",
        entries.len() + slams.len(),
        start.elapsed()
    );
    Ok(code)
}

/// A SLAM study is not sized by `--runs`, `--steps`, `--seed` or `--every`: refused when only
/// SLAM studies are reproduced (`alone`), said when filter studies take them.
fn check_slam_sizes(slams: &[&registry::Entry], alone: bool, over: &Overrides) -> Result<()> {
    if slams.is_empty() || !over.sizes_filter() {
        return Ok(());
    }
    let names: Vec<&str> = slams.iter().map(|e| e.name).collect();
    if alone {
        bail!("{}: {SLAM_SIZES}", names.join(", "));
    }
    eprintln!(
        "note: {} at the size of {}: {SLAM_SIZES}",
        names.join(", "),
        if names.len() == 1 {
            "its file"
        } else {
            "their files"
        }
    );
    Ok(())
}

/// The SLAM studies' identities and prepared directories (taken when each is committed).
type PreparedSlams = Vec<(StudyId, Option<outdir::Prepared>)>;

/// Every output directory of a reproduction, checked (and emptied with `force`) before anything
/// runs: the root holds one directory per simulation, and each holds its own study only.
fn prepare_reproductions(
    out: &Path,
    force: bool,
    files: &[(&str, Scenario)],
    slams: &[&registry::Entry],
) -> Result<(Vec<Option<outdir::Prepared>>, PreparedSlams)> {
    outdir::prepare_root(out, force, Hint::CLI)?;
    let mut prepared = Vec::new();
    for (file, sc) in files {
        let id = StudyId::study(sc.name());
        let dir = out.join(sim_dir(file));
        prepared.push(Some(outdir::prepare(&dir, &id, force, Hint::CLI)?));
    }
    let mut slam_prepared = Vec::new();
    for e in slams {
        let id = StudyId::new("slam", &slam::study_name(e.file, e.text)?);
        let p = outdir::prepare(&out.join(e.name), &id, force, Hint::CLI)?;
        slam_prepared.push((id, Some(p)));
    }
    Ok((prepared, slam_prepared))
}

/// The SLAM reproductions (`slam` studies), each into its prepared directory; with `pages`,
/// each one's HTML page too.
fn reproduce_slams(
    slams: &[&registry::Entry],
    prepared: &mut PreparedSlams,
    out: &Path,
    over: &Overrides,
    mut pages: Option<&mut Vec<PathBuf>>,
) -> Result<()> {
    for (e, (id, prep)) in slams.iter().zip(prepared.iter_mut()) {
        let dir = out.join(e.name);
        let st = slam::run_text(e.file, e.text, &dir, over.json)?;
        let prep = prep.take().context("each SLAM study is prepared once")?;
        commit(st, prep, id)?;
        eprintln!("{:<16} {}", e.name, dir.display());
        if let Some(pages) = pages.as_deref_mut() {
            pages.push(interrupt::critical(&dir.join("report.html"), || {
                report::write_page(&dir)
            })?);
        }
    }
    Ok(())
}

/// The registry entries `names` asks for (`all`: every one), each once, in the registry's order,
/// with every other figure of the simulations they run: a simulation's directory holds all its
/// figures, so reproducing one never removes another drawn from the same data (a re-run removes
/// the files it does not write again).
fn select_entries(names: &[String]) -> Result<Vec<&'static registry::Entry>> {
    if names.is_empty() {
        bail!("name the figures to reproduce (see `edgekf reproduce --list`), or `all`");
    }
    let mut files: Vec<&str> = Vec::new();
    for n in names.iter().filter(|n| *n != "all") {
        let e = registry::find(n).with_context(|| {
            format!("unknown figure `{n}`; `edgekf reproduce --list` prints the names")
        })?;
        files.push(e.file);
    }
    let all = names.iter().any(|n| n == "all");
    Ok(registry::ENTRIES
        .iter()
        .filter(|e| all || files.contains(&e.file))
        .collect())
}

/// Every scenario the entries simulate, checked before any runs so that a bad flag fails at
/// once: each file once, companions (further studies a figure draws) before the figures that
/// need them.
fn check_reproductions(
    entries: &[&'static registry::Entry],
    over: &Overrides,
    threads: usize,
) -> Result<Vec<(&'static str, Scenario)>> {
    let mut files: Vec<(&str, Scenario)> = Vec::new();
    for e in entries {
        for (file, text) in e.companions.iter().copied().chain([(e.file, e.text)]) {
            if files.iter().any(|(f, _)| *f == file) {
                continue;
            }
            let sc = load_with(file, text, over, &|t| {
                Ok(io::load_scenario_with(
                    file,
                    t,
                    &registry::embedded_framework,
                )?)
            })?;
            check_cost(&sc, sc.runs(), threads, over)?;
            files.push((file, sc));
        }
    }
    Ok(files)
}

/// The companion studies (scenario and sweep, already simulated) the entries `mine` draw.
fn companions<'a>(
    mine: &[&registry::Entry],
    files: &'a [(&str, Scenario)],
    done: &'a [(&str, Option<sim::sweep::SweepResults>)],
) -> Vec<(&'a Scenario, &'a sim::sweep::SweepResults)> {
    let mut out = Vec::new();
    for e in mine {
        for (cf, _) in e.companions {
            let csc = files.iter().find(|(f, _)| f == cf).map(|(_, s)| s);
            let csw = done
                .iter()
                .find(|(f, _)| f == cf)
                .and_then(|(_, w)| w.as_ref());
            if let (Some(csc), Some(csw)) = (csc, csw) {
                out.push((csc, csw));
            }
        }
    }
    out
}

/// The figures a simulation wrote and what it cost, on stderr.
fn print_reproduced(
    mine: &[&registry::Entry],
    dir: &Path,
    (file, sc, threads): (&str, &Scenario, usize),
    sweep: Option<&sim::sweep::SweepResults>,
    sim_time: std::time::Duration,
) {
    for e in mine {
        let pngs: Vec<String> = e
            .plots
            .iter()
            .map(|p| dir.join(format!("{p}.png")).display().to_string())
            .collect();
        eprintln!("{:<16} {}", e.name, pngs.join(", "));
    }
    eprintln!(
        "  ({file}: {} runs × {} steps{} simulated in {sim_time:.2?}; estimated {})",
        sc.runs(),
        sc.steps(),
        sweep
            .map(|w| format!(" × {} sweep values", w.points.len()))
            .unwrap_or_default(),
        sim::cost::human_seconds(sim::cost(sc, sc.runs(), threads).seconds),
    );
}
