//! `edgekf agent`, `edgekf world` and `edgekf swarm` (feature `swarm`): the agents as processes
//! over Zenoh (crate `edgekf-swarm`). `agent` and `world` are one process each and run across
//! machines with the endpoints given as flags (or a Zenoh configuration file); `swarm` starts
//! the world and one process per agent on this machine, kills agents on request
//! (`--kill AGENT@SECONDS`, SIGKILL), relays the first error, and leaves `--out` complete or
//! absent.

use std::collections::BTreeMap;
use std::fs;
use std::io::{BufRead, BufReader, Write as _};
use std::net::{TcpListener, UdpSocket};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use edgekf::scenario::Scenario;
use edgekf_swarm::agent_node::{run_agent, AgentOptions};
use edgekf_swarm::world_node::{run_world, WorldOptions, WorldOutcome};
use edgekf_swarm::{Endpoints, Mode};

use edgekf_io::outdir::{self, Hint, StudyId};

use crate::{interrupt, Overrides};

/// How the world steps.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeArg {
    /// The world waits for every present agent at every step; with no loss and no departure
    /// the outputs equal `edgekf run --runs 1`.
    Lockstep,
    /// A fixed clock of `--period-ms`; an output that misses its step's deadline is late.
    Realtime,
}

/// Where a swarm's communication failures come from.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommFailures {
    /// The world draws each link's failures with the scenario's `p_fail`, as `edgekf run`
    /// does (the same uniforms); a lossy network loses messages on top of them.
    Drawn,
    /// The world draws none: the messages the network loses (or delivers late) are the only
    /// failures, and `p_fail` is only the filters' model of them (a study of real loss).
    Network,
}

/// Where the processes meet and how they wait (the same for every process of a swarm).
#[derive(Args, Debug, Clone)]
pub struct NetArgs {
    /// The swarm's name: the first part of every Zenoh key (several swarms can share a
    /// network).
    #[arg(long, default_value = "edgekf")]
    pub swarm: String,
    /// The world's Zenoh endpoint (TCP): the world listens there, every agent connects.
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    pub world: String,
    /// Agent i listens on UDP port MESH_BASE_PORT + i for its neighbours (the mesh).
    #[arg(long, default_value_t = 17500)]
    pub mesh_base_port: u16,
    /// The hosts of the agents' mesh endpoints: one for all, or one per agent (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "127.0.0.1")]
    pub mesh_hosts: Vec<String>,
    /// A Zenoh configuration file (JSON5) the sessions start from (the flags above override
    /// its endpoints, mode and scouting).
    #[arg(long)]
    pub zenoh_config: Option<PathBuf>,
    #[command(flatten)]
    pub timing: Timing,
}

/// How the processes of a swarm step and wait (the same for every process).
#[derive(Args, Debug, Clone)]
pub struct Timing {
    /// Timing mode.
    #[arg(long, value_enum, default_value = "lockstep")]
    pub mode: ModeArg,
    /// The period of a step in real time, in ms.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub period_ms: u64,
    /// The mesh may lose messages: a lockstep agent waits at most --grace-ms for a neighbour's
    /// message, then treats it as lost (its filters fall back on their comm models).
    #[arg(long)]
    pub lossy: bool,
    /// See --lossy.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(0..=60_000))]
    pub grace_ms: u64,
    /// Agents may leave (a killed or crashed process, e.g. `kill -9`): presence is tracked every
    /// step and the filters read it (implied by --lossy, --mode realtime and `swarm --kill`).
    #[arg(long)]
    pub live: bool,
    /// The bound of every wait, in seconds: a world that never starts, an agent or neighbour
    /// that never answers, an endpoint nobody listens on.
    #[arg(long, default_value_t = 20.0, value_parser = seconds)]
    pub timeout_s: f64,
}

fn seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 86_400.0 => Ok(v),
        _ => Err(format!(
            "must be a number of seconds in (0, 86400], got `{s}`"
        )),
    }
}

impl NetArgs {
    /// The mesh's hosts and ports fit `n` agents: one host for all or one per agent, and
    /// every agent's port `MESH_BASE_PORT + i` at most 65535.
    fn check(&self, n: usize) -> Result<()> {
        let hosts = self.mesh_hosts.len();
        if hosts != 1 && hosts != n {
            bail!(
                "flag `--mesh-hosts`: {hosts} hosts for {n} agents: give one for all, or one per agent"
            );
        }
        let last = usize::from(self.mesh_base_port) + n - 1;
        if last > usize::from(u16::MAX) {
            bail!(
                "flag `--mesh-base-port`: {} + {n} agents needs ports up to {last}, past 65535",
                self.mesh_base_port
            );
        }
        Ok(())
    }

    fn endpoints(&self) -> Endpoints {
        Endpoints {
            swarm: self.swarm.clone(),
            world: self.world.clone(),
            mesh_base_port: self.mesh_base_port,
            mesh_hosts: self.mesh_hosts.clone(),
            zenoh_config: self.zenoh_config.clone(),
        }
    }

    fn mode(&self) -> Mode {
        match self.timing.mode {
            ModeArg::Lockstep => Mode::Lockstep,
            ModeArg::Realtime => Mode::Realtime {
                period: Duration::from_millis(self.timing.period_ms),
            },
        }
    }

    fn live(&self) -> bool {
        self.timing.live || self.timing.lossy || self.timing.mode == ModeArg::Realtime
    }

    /// The flags that reproduce these settings in a child process.
    fn to_args(&self) -> Vec<String> {
        let mut a = vec![
            "--swarm".into(),
            self.swarm.clone(),
            "--world".into(),
            self.world.clone(),
            "--mesh-base-port".into(),
            self.mesh_base_port.to_string(),
            "--mesh-hosts".into(),
            self.mesh_hosts.join(","),
            "--mode".into(),
            format!("{:?}", self.timing.mode).to_lowercase(),
            "--period-ms".into(),
            self.timing.period_ms.to_string(),
            "--grace-ms".into(),
            self.timing.grace_ms.to_string(),
            "--timeout-s".into(),
            self.timing.timeout_s.to_string(),
        ];
        if let Some(c) = &self.zenoh_config {
            a.extend(["--zenoh-config".into(), c.display().to_string()]);
        }
        for (on, flag) in [(self.timing.lossy, "--lossy"), (self.timing.live, "--live")] {
            if on {
                a.push(flag.into());
            }
        }
        a
    }
}

/// `edgekf agent`.
#[derive(Args, Debug)]
pub struct AgentArgs {
    /// Scenario file (TOML or a resolved scenario.json): the same as the world's.
    pub scenario: PathBuf,
    /// This agent's id (0-based).
    #[arg(long)]
    pub id: usize,
    #[command(flatten)]
    pub net: NetArgs,
    #[command(flatten)]
    pub over: Overrides,
}

/// `edgekf world`.
#[derive(Args, Debug)]
pub struct WorldArgs {
    /// Scenario file (TOML or a resolved scenario.json): the same as the agents'.
    pub scenario: PathBuf,
    /// Output directory: the files of `edgekf run`, and network.csv.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the output directory's contents when it holds files of another study (once the
    /// new files are in place: an interrupted swarm leaves the old ones).
    #[arg(long)]
    pub force: bool,
    /// A shell command run once every agent is ready, before the first step (e.g. an nftables
    /// rule that makes the mesh lossy: see docs/agents.md, "Real packet loss").
    #[arg(long)]
    pub after_ready: Option<String>,
    /// Where the filters' communication failures come from (see docs/agents.md, "How the
    /// network's loss maps onto P_fail").
    #[arg(long, value_enum, default_value = "drawn")]
    pub comm_failures: CommFailures,
    /// Print `progress K` on stdout after every step (for `edgekf swarm`).
    #[arg(long, hide = true)]
    pub progress_lines: bool,
    #[command(flatten)]
    pub net: NetArgs,
    #[command(flatten)]
    pub over: Overrides,
}

/// `edgekf swarm`.
#[derive(Args, Debug)]
pub struct SwarmArgs {
    /// Scenario file (TOML or a resolved scenario.json).
    pub scenario: PathBuf,
    /// Output directory: the files of `edgekf run --runs 1`, and network.csv.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the output directory's contents when it holds files of another study (once the
    /// new files are in place: an interrupted swarm leaves the old ones).
    #[arg(long)]
    pub force: bool,
    /// SIGKILL agent AGENT's process at simulated time SECONDS (repeatable), e.g. `--kill 3@5`.
    #[arg(long, value_parser = parse_kill)]
    pub kill: Vec<(usize, f64)>,
    /// A shell command run once every agent is ready, before the first step.
    #[arg(long)]
    pub after_ready: Option<String>,
    /// Also write report.html.
    #[arg(long)]
    pub report: bool,
    /// Where the filters' communication failures come from: the scenario's `p_fail` drawn by
    /// the world (as `edgekf run`), or only the network's losses (with `--lossy`, for a study of
    /// real loss; `p_fail` is then the filters' model only).
    #[arg(long, value_enum, default_value = "drawn")]
    pub comm_failures: CommFailures,
    #[command(flatten)]
    pub timing: Timing,
    /// A Zenoh configuration file (JSON5) for every process.
    #[arg(long)]
    pub zenoh_config: Option<PathBuf>,
    #[command(flatten)]
    pub over: Overrides,
}

fn parse_kill(s: &str) -> Result<(usize, f64), String> {
    let bad = || format!("expected AGENT@SECONDS (e.g. 3@5.0), got `{s}`");
    let (a, t) = s.split_once('@').ok_or_else(bad)?;
    let a = a.trim().parse::<usize>().map_err(|_| bad())?;
    let t = t.trim().parse::<f64>().map_err(|_| bad())?;
    if !(t.is_finite() && t >= 0.0) {
        return Err(format!("the time of `--kill {s}` must be ≥ 0 s"));
    }
    Ok((a, t))
}

/// The scenario of a swarm: one run (run 0 of `edgekf run`), the overrides applied.
fn scenario(path: &Path, over: &Overrides) -> Result<Scenario> {
    if over.runs.is_some_and(|r| r != 1) {
        bail!("flag `--runs`: a swarm is one run (run 0 of `edgekf run`); run several swarms with different --seed for more");
    }
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    if let crate::io::Kind::Slam = crate::io::kind_of(&text) {
        bail!(
            "{}: a SLAM scenario (Guo et al.'s observer) does not run as a swarm: it is simulated as one continuous-time system (RK4); run it with `edgekf run`",
            path.display()
        );
    }
    let mut over = over.clone();
    over.runs = Some(1);
    let sc = crate::load(&path.display().to_string(), &text, path.parent(), &over)?;
    if sc.sweep().is_some() {
        bail!(
            "{}: key `sweep`: a swarm runs one scenario, not a sweep's values; run the sweep with `edgekf run`, or a swarm of each value's scenario (the sweep's parameter set in a copy without `[sweep]`)",
            path.display()
        );
    }
    Ok(sc)
}

/// Seconds a lockstep step of `n` agents takes on this 2-core machine: a power law through
/// the swarm chapter's two measured rates (N = 10: 1,046–1,084 steps/s; N = 50: 119–164).
fn lockstep_step_seconds(n: usize) -> f64 {
    (n as f64 / 10.0).powf(1.26) / 1065.0
}

/// Refuses a swarm estimated to take longer than `--max-hours` (real time: the period per
/// step; lockstep: [`lockstep_step_seconds`]), and announces one longer than a minute.
fn check_swarm_time(sc: &Scenario, timing: &Timing, over: &Overrides) -> Result<()> {
    let steps = sc.steps() as f64;
    let (seconds, how) = match timing.mode {
        ModeArg::Realtime => (
            steps * timing.period_ms as f64 / 1000.0,
            format!("{} ms a step in real time", timing.period_ms),
        ),
        ModeArg::Lockstep => (
            steps * lockstep_step_seconds(sc.framework().agents()),
            "the lockstep rate measured for its size".to_string(),
        ),
    };
    let human = edgekf::sim::cost::human_seconds(seconds);
    if seconds > over.max_hours * 3600.0 {
        bail!(
            "{}: this swarm would take about {human} ({} steps at {how}); the limit is {} h (`--max-hours`, default {} h; raise it to run it anyway). Lower `steps` (`--steps`)",
            sc.name(),
            sc.steps(),
            over.max_hours,
            crate::DEFAULT_MAX_HOURS
        );
    }
    if seconds > 60.0 {
        eprintln!(
            "{}: estimated {human} ({} steps at {how})",
            sc.name(),
            sc.steps()
        );
    }
    Ok(())
}

/// Runs `edgekf agent`.
///
/// # Errors
/// As [`run_agent`], named.
pub fn agent(args: &AgentArgs) -> Result<ExitCode> {
    let sc = scenario(&args.scenario, &args.over)?;
    args.net.check(sc.framework().agents())?;
    let o = AgentOptions {
        id: args.id,
        endpoints: args.net.endpoints(),
        mode: args.net.mode(),
        lossy: args.net.timing.lossy,
        live: args.net.live(),
        grace: Duration::from_millis(args.net.timing.grace_ms),
        timeout: Duration::from_secs_f64(args.net.timing.timeout_s),
    };
    run_agent(&sc, &o)?;
    Ok(ExitCode::SUCCESS)
}

/// Runs `edgekf world`: the world, then its outputs.
///
/// # Errors
/// As [`run_world`], and the outputs' writing.
pub fn world(args: &WorldArgs) -> Result<ExitCode> {
    let sc = scenario(&args.scenario, &args.over)?;
    edgekf::agent::Agent::new(&sc, 0, false)
        .with_context(|| args.scenario.display().to_string())?;
    check_swarm_time(&sc, &args.net.timing, &args.over)?;
    args.net.check(sc.framework().agents())?;
    warn_unmodelled_loss(&sc, &args.net.timing);
    let id = StudyId::new("swarm", sc.name());
    let prep = outdir::prepare(&args.out, &id, args.force, Hint::CLI)?;
    let o = WorldOptions {
        endpoints: args.net.endpoints(),
        mode: args.net.mode(),
        live: args.net.live(),
        timeout: Duration::from_secs_f64(args.net.timing.timeout_s),
        after_ready: args.after_ready.clone(),
        drawn_failures: args.comm_failures == CommFailures::Drawn,
        frames: edgekf_io::frames::frame_options(&sc),
    };
    let lines = args.progress_lines;
    let mut on_step = |k: usize| {
        if lines {
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "progress {k}");
            let _ = out.flush();
        }
    };
    let outcome = run_world(&sc, &o, &mut on_step)?;
    let mut st = interrupt::stage(&args.out)?;
    crate::stage_outputs(&mut st, &sc, &outcome.results, None, &Default::default())?;
    st.write("status.csv", status_csv(&outcome).as_bytes())?;
    st.write("network.csv", outcome.network.csv().as_bytes())?;
    crate::commit(st, prep, &id)?;
    let summary = summary_line(&sc, &outcome);
    if lines {
        // The supervisor relays it (the world's stderr goes to its log).
        println!("summary {summary}");
    } else {
        eprintln!("{summary}");
    }
    eprintln!("wrote {}", args.out.display());
    Ok(crate::report(&sc, &outcome.results, &args.over))
}

/// `status.csv` with a row per departed agent.
fn status_csv(o: &WorldOutcome) -> String {
    let mut s = edgekf_io::status_csv(&o.results);
    for d in &o.departures {
        s.push_str(&format!(
            "agent:{},departed,{},{},0,\"{}\"\n",
            d.agent,
            d.step,
            d.step as f64 * o.results.dt,
            d.how.replace('"', "'")
        ));
    }
    s
}

fn summary_line(sc: &Scenario, o: &WorldOutcome) -> String {
    let inputs = o.network.total("input");
    let lost = if inputs.sent > 0 {
        format!(
            "{:.2} % of {} mesh messages lost ({} late)",
            100.0 * inputs.lost as f64 / inputs.sent as f64,
            inputs.sent,
            inputs.late
        )
    } else {
        "no mesh messages".into()
    };
    format!(
        "swarm {}: {} steps at {:.0} steps/s; {} of {} outputs missed their deadline; {lost}; input latency p50 {:.3} ms, p99 {:.3} ms",
        sc.name(),
        sc.steps(),
        o.steps_per_s,
        o.deadline_misses,
        o.outputs_expected,
        inputs.quantile_ms(0.5),
        inputs.quantile_ms(0.99),
    )
}

/// A free TCP port on loopback.
fn free_tcp_port() -> Result<u16> {
    let l = TcpListener::bind("127.0.0.1:0").context("no free TCP port on 127.0.0.1")?;
    Ok(l.local_addr()?.port())
}

/// A base port with `n` consecutive free UDP ports on loopback.
fn free_udp_base(n: usize) -> Result<u16> {
    let seed = std::process::id() as usize;
    for attempt in 0..200 {
        let base = 20_000 + (seed * 7919 + attempt * 104_729) % (40_000 - n.min(20_000));
        let ok = (0..n).all(|i| UdpSocket::bind(("127.0.0.1", (base + i) as u16)).is_ok());
        if ok {
            return Ok(base as u16);
        }
    }
    bail!("no {n} consecutive free UDP ports on 127.0.0.1")
}

/// Zenoh's runtimes (RON, read by the `zenoh` crate at start-up) for a swarm on one machine:
/// the acceptor, application and network runtimes handed over to the receiving one, so that a
/// process's Zenoh work is two threads (rx and tx), not five. A UDP datagram that comes to a
/// listener is read by the acceptor's task and handed to the link's receiving task: on one
/// thread that is no wake-up between threads (half the swarm's context switches went there).
/// The transmitting runtime stays apart: handed over too, the sessions do not open.
const ZENOH_RUNTIME_ONE_MACHINE: &str = "(rx:(worker_threads:1),tx:(max_blocking_threads:1),\
    acc:(handover:rx),app:(handover:rx),net:(handover:rx))";

/// A child process of the swarm, killed with the parent (PR_SET_PDEATHSIG) and on Ctrl-C.
fn spawn(exe: &Path, args: &[String], stdout: Stdio, log: &Path) -> Result<Child> {
    let err = fs::File::create(log).with_context(|| format!("cannot create {}", log.display()))?;
    let mut cmd = Command::new(exe);
    cmd.args(args)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(err);
    // The study's provenance (the world writes it) records the command the user typed, not the
    // world's own.
    if args.first().is_some_and(|a| a == "world") {
        let typed: Vec<String> = std::env::args().collect();
        cmd.env(crate::INVOKED_AS, serde_json::to_string(&typed)?);
    }
    if std::env::var_os("ZENOH_RUNTIME").is_none() {
        // N + 1 processes share this machine's cores: one thread per Zenoh runtime, not
        // Zenoh's default pools (fewer wake-ups between threads; docs/agents.md).
        cmd.env("ZENOH_RUNTIME", ZENOH_RUNTIME_ONE_MACHINE);
    }
    // SAFETY: prctl(2) in the child before exec, async-signal-safe.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
    let child = cmd
        .spawn()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    interrupt::child(child.id());
    Ok(child)
}

/// The last lines of a log that say something.
fn tail(log: &Path) -> String {
    let text = fs::read_to_string(log).unwrap_or_default();
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        return "(it wrote no message)".into();
    }
    lines[lines.len().saturating_sub(3)..].join("\n  ")
}

/// Peak resident memory of a process, in MB (Linux `/proc`).
fn rss_mb(pid: u32) -> Option<f64> {
    let s = fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: f64 = s
        .lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// Runs `edgekf swarm`.
///
/// # Errors
/// A bad scenario or flag (before anything starts), a process that fails (its message), or
/// the outputs' writing.
pub fn swarm(args: &SwarmArgs) -> Result<ExitCode> {
    let sc = scenario(&args.scenario, &args.over)?;
    let n = sc.framework().agents();
    edgekf::agent::Agent::new(&sc, 0, false)
        .with_context(|| format!("{}", args.scenario.display()))?;
    check_swarm_time(&sc, &args.timing, &args.over)?;
    warn_unmodelled_loss(&sc, &args.timing);
    let kills = kill_steps(&args.kill, &sc)?;
    if !args.force {
        // Refused now, before any process starts (with --force the world replaces it at the end).
        let _unchanged = outdir::prepare(
            &args.out,
            &StudyId::new("swarm", sc.name()),
            false,
            Hint::CLI,
        )?;
    }
    let out_existed = args.out.exists();
    let exe = std::env::current_exe().context("cannot find this program's executable")?;
    let logs = std::env::temp_dir().join(format!("edgekf-swarm-{}", std::process::id()));
    fs::create_dir_all(&logs).with_context(|| format!("cannot create {}", logs.display()))?;
    interrupt::remove_on_interrupt(&logs);
    let (world_args, agent_args) = child_args(args, n)?;
    let started = Instant::now();
    let mut world = spawn(&exe, &world_args, Stdio::piped(), &logs.join("world.log"))?;
    interrupt::remove_on_interrupt(&edgekf_io::staging_dir_of(&args.out, world.id()));
    if !out_existed {
        interrupt::remove_if_empty_on_interrupt(&args.out);
    }
    let mut agents: Vec<Option<Child>> = Vec::with_capacity(n);
    for (i, a) in agent_args.iter().enumerate() {
        agents.push(Some(spawn(
            &exe,
            a,
            Stdio::null(),
            &logs.join(format!("agent-{i}.log")),
        )?));
    }
    let t = &args.timing;
    let live = t.live || !kills.is_empty() || t.lossy || t.mode == ModeArg::Realtime;
    let run = supervise(&mut world, &mut agents, (&kills, live), &logs);
    for a in agents.iter_mut().flatten() {
        let _ = a.kill();
        let _ = a.wait();
    }
    let _ = world.kill();
    let _ = world.wait();
    if let Ok(peak) = &run {
        print_memory(peak, started);
    }
    let _ = fs::remove_dir_all(&logs);
    run?;
    if args.report {
        crate::report::write_page(&args.out)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// On a mesh that may lose messages (`--lossy`, or real time, where a late message is lost), an
/// estimator that models link failures at `p_fail = 0` predicts a lost input but keeps the
/// covariance of a filter that loses none: said on stderr, with what to do.
fn warn_unmodelled_loss(sc: &Scenario, t: &Timing) {
    if !(t.lossy || t.mode == ModeArg::Realtime) {
        return;
    }
    for def in sc.estimators() {
        if def.config().link_failure() == Some(0.0) {
            eprintln!(
                "edgekf: warning: estimator `{}` has p_fail = 0 but the mesh may lose messages: it predicts a lost input, but its covariance does not count the loss; give p_fail the network's loss rate",
                def.label()
            );
        }
    }
}

/// `--kill AGENT@SECONDS` as steps, checked against the scenario.
fn kill_steps(kill: &[(usize, f64)], sc: &Scenario) -> Result<BTreeMap<usize, usize>> {
    let n = sc.framework().agents();
    let horizon = sc.steps() as f64 * sc.dt();
    let mut kills = BTreeMap::new();
    for &(a, t) in kill {
        if a >= n {
            bail!(
                "flag `--kill {a}@{t}`: agent {a} is out of range: the scenario has agents 0..{n}"
            );
        }
        if t >= horizon {
            bail!("flag `--kill {a}@{t}`: {t} s is at or past the end of the run ({horizon} s)");
        }
        kills.insert(a, ((t / sc.dt()).floor() as usize).max(1));
    }
    Ok(kills)
}

/// The command lines of the world and of each agent: fresh endpoints on loopback.
fn child_args(args: &SwarmArgs, n: usize) -> Result<(Vec<String>, Vec<Vec<String>>)> {
    let net = NetArgs {
        swarm: format!("swarm-{}", std::process::id()),
        world: format!("tcp/127.0.0.1:{}", free_tcp_port()?),
        mesh_base_port: free_udp_base(n)?,
        mesh_hosts: vec!["127.0.0.1".into()],
        zenoh_config: args.zenoh_config.clone(),
        timing: Timing {
            live: args.timing.live || !args.kill.is_empty(),
            ..args.timing.clone()
        },
    };
    let scenario_arg = args.scenario.display().to_string();
    let mut common = net.to_args();
    common.extend(over_args(&args.over));
    let mut world = vec!["world".into(), scenario_arg.clone(), "--out".into()];
    world.push(args.out.display().to_string());
    world.push("--progress-lines".into());
    if args.force {
        world.push("--force".into());
    }
    if let Some(cmd) = &args.after_ready {
        world.extend(["--after-ready".into(), cmd.clone()]);
    }
    if args.comm_failures == CommFailures::Network {
        world.extend(["--comm-failures".into(), "network".into()]);
    }
    world.extend(common.clone());
    let agents = (0..n)
        .map(|i| {
            let mut a = vec![
                "agent".into(),
                scenario_arg.clone(),
                "--id".into(),
                i.to_string(),
            ];
            a.extend(common.clone());
            a
        })
        .collect();
    Ok((world, agents))
}

/// The agents' peak memory and the swarm's wall time, on stderr.
fn print_memory(peak: &[Option<f64>], started: Instant) {
    let peaks: Vec<f64> = peak.iter().flatten().copied().collect();
    if !peaks.is_empty() {
        let mean = peaks.iter().sum::<f64>() / peaks.len() as f64;
        let max = peaks.iter().copied().fold(0.0, f64::max);
        eprintln!(
            "memory per agent process: peak RSS {mean:.1} MB on average, {max:.1} MB at most ({} processes); wall time {:.1} s",
            peaks.len(),
            started.elapsed().as_secs_f64()
        );
    }
}

/// The overrides as flags for the children.
fn over_args(o: &Overrides) -> Vec<String> {
    let mut a = Vec::new();
    for (flag, v) in [("--steps", o.steps), ("--every", o.every)] {
        if let Some(v) = v {
            a.extend([flag.to_string(), v.to_string()]);
        }
    }
    if let Some(s) = o.seed {
        a.extend(["--seed".to_string(), s.to_string()]);
    }
    if o.allow_divergence {
        a.push("--allow-divergence".into());
    }
    if o.json {
        a.push("--json".into());
    }
    a.extend(["--max-hours".to_string(), o.max_hours.to_string()]);
    a
}

/// Follows the world's progress, kills agents on time, relays the world's other output, and
/// returns each agent process's peak memory when the world is done.
fn supervise(
    world: &mut Child,
    agents: &mut [Option<Child>],
    (kills, live): (&BTreeMap<usize, usize>, bool),
    logs: &Path,
) -> Result<Vec<Option<f64>>> {
    let (tx, rx) = mpsc::channel::<String>();
    let stdout = world.stdout.take().context("the world's output")?;
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut peak: Vec<Option<f64>> = vec![None; agents.len()];
    let mut last_sample = Instant::now();
    loop {
        match rx.recv_timeout(Duration::from_millis(50)) {
            Ok(line) => match line.strip_prefix("progress ") {
                Some(k) => {
                    let k: usize = k.trim().parse().unwrap_or(0);
                    if k == 1 {
                        eprintln!("edgekf swarm: {} agents ready; stepping", agents.len());
                    }
                    kill_due(kills, k, agents, &mut peak);
                }
                None => match line.strip_prefix("summary ") {
                    Some(summary) => eprintln!("edgekf {summary}"),
                    None => println!("{line}"),
                },
            },
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                // The world closed its output: it is ending.
                let status = world.wait().context("waiting for the world")?;
                for (i, a) in agents.iter().enumerate() {
                    if let Some(c) = a {
                        peak[i] = peak[i].or(rss_mb(c.id()));
                    }
                }
                if status.success() {
                    wait_agents(agents, logs, live)?;
                    return Ok(peak);
                }
                bail!("{}", failure(agents, logs));
            }
        }
        if !live {
            if let Some(msg) = ended_early(agents, logs) {
                let _ = world.kill();
                bail!("{msg}");
            }
        }
        if last_sample.elapsed() > Duration::from_millis(500) {
            last_sample = Instant::now();
            for (i, a) in agents.iter().enumerate() {
                if let Some(c) = a {
                    peak[i] = rss_mb(c.id()).or(peak[i]);
                }
            }
        }
    }
}

/// `--kill`: SIGKILL each agent whose step comes next after step `k` (its peak memory kept).
fn kill_due(
    kills: &BTreeMap<usize, usize>,
    k: usize,
    agents: &mut [Option<Child>],
    peak: &mut [Option<f64>],
) {
    for (&a, &at) in kills {
        if k + 1 >= at {
            if let Some(mut c) = agents[a].take() {
                peak[a] = rss_mb(c.id());
                let _ = c.kill(); // SIGKILL
                let _ = c.wait();
            }
        }
    }
}

/// In a swarm that is not live, an agent that failed before the world ended (a crash,
/// `kill -9`): the world would wait `--timeout-s` for its output and then fail, so the swarm
/// ends now, naming it. (An agent that exits with success was told to stop: the world is
/// writing its outputs.)
fn ended_early(agents: &mut [Option<Child>], logs: &Path) -> Option<String> {
    agents.iter_mut().enumerate().find_map(|(i, a)| {
        let s = a.as_mut()?.try_wait().ok()??;
        (!s.success()).then(|| format!(
            "agent {i} ended before the swarm did ({s}):\n  {}\na swarm without --live needs every agent to the last step; with --live (or --lossy, --mode realtime, --kill) an agent that ends is a departure",
            tail(&logs.join(format!("agent-{i}.log")))
        ))
    })
}

/// The agents end after the world's stop; one that fails is named (in a live swarm, one
/// killed by a signal departed: the world has its row).
fn wait_agents(agents: &mut [Option<Child>], logs: &Path, live: bool) -> Result<()> {
    use std::os::unix::process::ExitStatusExt as _;
    let deadline = Instant::now() + Duration::from_secs(10);
    for (i, a) in agents.iter_mut().enumerate() {
        let Some(c) = a else { continue };
        loop {
            match c.try_wait()? {
                Some(s) if s.success() || (live && s.signal().is_some()) => break,
                Some(s) => bail!(
                    "agent {i} failed ({s}):\n  {}",
                    tail(&logs.join(format!("agent-{i}.log")))
                ),
                None if Instant::now() > deadline => {
                    let _ = c.kill();
                    break;
                }
                None => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    }
    Ok(())
}

/// The world's error, with the first agent error that explains it.
fn failure(agents: &mut [Option<Child>], logs: &Path) -> String {
    let mut msg = format!("the world failed:\n  {}", tail(&logs.join("world.log")));
    for (i, a) in agents.iter_mut().enumerate() {
        if let Some(c) = a {
            if let Ok(Some(s)) = c.try_wait() {
                if !s.success() {
                    msg.push_str(&format!(
                        "\nagent {i} failed ({s}):\n  {}",
                        tail(&logs.join(format!("agent-{i}.log")))
                    ));
                    break;
                }
            }
        }
    }
    msg
}
