//! `edgekf design`: design the stress (Laplacian weights) of a framework, check it, and write
//! `DIR/framework.json` (schema `edgekf.framework/1`, edges reduced to nonzero-weight links) and
//! `DIR/framework.png`.
//!
//! The configuration and candidate links come from a framework file (weights absent or ignored)
//! or from a generator. Infeasible input ends with an error naming the failed condition.

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context};
use edgekf::design::{self, generators, Candidate, CheckReport, LeaderMode, Method};
use edgekf::framework::Framework;
use rand::SeedableRng;

pub use edgekf_io::framework::{FrameworkFile, FRAMEWORK_SCHEMA};

/// Generators of `--generate`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Generator {
    /// The thesis hexagon: 10 agents, 30 links, leaders 0–2.
    Hexagon,
    /// Its 3-D counterpart: 11 agents, 40 links, leaders 0–3.
    Hexagon3d,
    /// Random D-trilateration graph (`--agents`, `--dim`, `--seed`): uniform points, each agent
    /// linked to its D + 2 nearest earlier agents.
    Trilateration,
    /// Li & Rajan Fig. 13a, 50 random agents, candidates for a sparse design (`--seed`).
    Random50Sparse,
    /// Li & Rajan Fig. 13a, 50 random agents, complete candidate graph (`--seed`).
    Random50Dense,
    /// Complete graph on random points (`--agents`, `--dim`, `--seed`).
    Complete,
    /// Sparse candidates just above the rigidity threshold (`--agents`, `--dim`, `--neighbours`,
    /// `--seed`): each agent linked to its D + 1 nearest earlier agents (a D-trilateration
    /// backbone) plus every agent's `--neighbours` nearest agents; unit density.
    Backbone,
    /// Zhao's 7-agent affine-maneuver example (IEEE TAC 2018): 12 links, leaders 0, 1, 2 not all
    /// linked.
    Zhao7,
}

/// Design methods of `--method`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodArg {
    /// Thesis SDP (3.5), best-conditioned form.
    Sdp,
    /// Yang et al. 2019 construction (designs the graph too).
    Yang,
    /// ℓ1-penalised sparse design (Li, Leus & Rajan 2025).
    Sparse,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Sdp => Method::Sdp,
            MethodArg::Yang => Method::Yang,
            MethodArg::Sparse => Method::Sparse,
        }
    }
}

/// How `--leaders auto` chooses.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeaderModeArg {
    /// D + 1 mutually linked agents (the distance-based leader law needs them).
    Clique,
    /// Any D + 1 affinely independent agents (leaders that track a target).
    Affine,
}

impl From<LeaderModeArg> for LeaderMode {
    fn from(m: LeaderModeArg) -> Self {
        match m {
            LeaderModeArg::Clique => LeaderMode::Clique,
            LeaderModeArg::Affine => LeaderMode::Affine,
        }
    }
}

/// What `--leaders` asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LeadersArg {
    /// Choose after the design (`auto`).
    Auto,
    /// No leaders (`none`).
    None,
    /// These agents (`i,j,k`).
    List(Vec<usize>),
}

impl std::str::FromStr for LeadersArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(LeadersArg::Auto),
            "none" => Ok(LeadersArg::None),
            list => list
                .split(',')
                .map(|t| t.trim().parse::<usize>())
                .collect::<Result<Vec<_>, _>>()
                .map(LeadersArg::List)
                .map_err(|_| {
                    format!("--leaders takes auto, none or a list like 0,1,2; got {list:?}")
                }),
        }
    }
}

/// Arguments of `edgekf design`.
#[derive(clap::Args, Debug)]
pub struct DesignArgs {
    /// Framework file (`edgekf.framework/1`): configuration, candidate links, optional leaders.
    #[arg(conflicts_with = "generate", required_unless_present = "generate")]
    pub input: Option<PathBuf>,
    /// Generate the configuration and candidate links instead of reading a file.
    #[arg(long, value_enum)]
    pub generate: Option<Generator>,
    /// Number of agents (trilateration, complete).
    #[arg(long, default_value_t = 20)]
    pub agents: usize,
    /// Dimension D (trilateration, complete).
    #[arg(long, default_value_t = 2)]
    pub dim: usize,
    /// Nearest neighbours added to the backbone generator's links.
    #[arg(long, default_value_t = 2)]
    pub neighbours: usize,
    /// Seed of the random generators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Design method.
    #[arg(long, value_enum, default_value = "sdp")]
    pub method: MethodArg,
    /// Leaders: `auto` (chosen after the design to maximise λ_min(L_ff), see
    /// `--leader-mode`), `none`, or a list `i,j,k`. Default: the input's (or generator's).
    #[arg(long)]
    pub leaders: Option<LeadersArg>,
    /// How `--leaders auto` chooses: a mutually linked clique (for the distance-based leader
    /// law) or any affinely independent agents (for target tracking).
    #[arg(long, value_enum, default_value = "clique")]
    pub leader_mode: LeaderModeArg,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the output directory's contents when it holds files of another study or design
    /// (once the new files are in place).
    #[arg(long)]
    pub force: bool,
    /// Refuse a design estimated to take longer than this many hours (the estimate is checked
    /// before the candidates are generated; one that needs more than 80 % of the available
    /// memory is refused too).
    #[arg(long, default_value_t = crate::DEFAULT_MAX_HOURS, value_parser = crate::hours)]
    pub max_hours: f64,
}

/// Refuses a design whose estimate ([`design::cost`]) is past the memory or time limit, naming
/// the flags that change it.
#[allow(clippy::too_many_arguments)]
fn check_cost(
    what: &str,
    n: usize,
    dim: usize,
    links: f64,
    generation: design::cost::Generation,
    method: Method,
    max_hours: f64,
    size_flags: &str,
) -> anyhow::Result<()> {
    let c = design::cost::estimate(n, dim, links, generation, method);
    let human_b = edgekf::sim::cost::human_bytes;
    let human_s = edgekf::sim::cost::human_seconds;
    if let Some(avail) = crate::available_memory() {
        if c.bytes > crate::MEMORY_SHARE * avail {
            bail!(
                "{what}: the design needs about {} of memory ({n} agents in {dim}-D, {links:.0} candidate links) but {} is available (the limit is 80 % of it); {size_flags}",
                human_b(c.bytes),
                human_b(avail)
            );
        }
    }
    if c.seconds > max_hours * 3600.0 {
        bail!(
            "{what}: the design would take about {} ({n} agents in {dim}-D, {links:.0} candidate links, method {method:?}); the limit is {max_hours} h (`--max-hours`, default {} h; raise it to run it anyway); {size_flags}",
            human_s(c.seconds),
            crate::DEFAULT_MAX_HOURS
        );
    }
    if c.seconds > 60.0 {
        eprintln!(
            "{what}: estimated {}, {} of memory",
            human_s(c.seconds),
            human_b(c.bytes)
        );
    }
    Ok(())
}

/// The candidate links a generator makes, and how (before it runs).
fn generated_size(args: &DesignArgs, which: Generator) -> Option<(f64, design::cost::Generation)> {
    use design::cost::{complete_links, Generation};
    let (n, d) = (args.agents as f64, args.dim as f64);
    match which {
        Generator::Trilateration => Some((n * (d + 2.0), Generation::Nearest)),
        Generator::Backbone => Some((n * (d + 1.0 + args.neighbours as f64), Generation::Nearest)),
        Generator::Complete => Some((complete_links(args.agents), Generation::Complete)),
        _ => None,
    }
}

fn generate(args: &DesignArgs, which: Generator) -> anyhow::Result<Candidate> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(args.seed);
    let needs = |what: &str| -> anyhow::Result<()> {
        if !(1..=3).contains(&args.dim) {
            bail!("--dim must be 1, 2 or 3 for {what}, got {}", args.dim);
        }
        if args.agents < args.dim + 2 {
            bail!(
                "--agents must be at least D + 2 = {} for {what}, got {}",
                args.dim + 2,
                args.agents
            );
        }
        Ok(())
    };
    Ok(match which {
        Generator::Hexagon => generators::hexagon_candidate(),
        Generator::Hexagon3d => generators::hexagon3d_candidate(),
        Generator::Trilateration => {
            needs("trilateration")?;
            generators::trilateration(args.agents, args.dim, args.dim + 2, &mut rng)
        }
        Generator::Backbone => {
            needs("backbone")?;
            let side = (args.agents as f64).powf(1.0 / args.dim as f64);
            generators::backbone(
                args.agents,
                &vec![side; args.dim],
                args.neighbours,
                &mut rng,
            )
        }
        Generator::Zhao7 => generators::zhao7_candidate(),
        Generator::Random50Sparse => generators::random50(generators::Density::Sparse, &mut rng),
        Generator::Random50Dense => generators::random50(generators::Density::Dense, &mut rng),
        Generator::Complete => {
            needs("complete")?;
            let extent = (args.agents as f64).powf(1.0 / args.dim as f64);
            let config = generators::random_config(args.agents, args.dim, extent, &mut rng);
            generators::complete(
                &format!("complete-{}d-n{}", args.dim, args.agents),
                args.dim,
                config,
            )
        }
    })
}

fn read_input(path: &Path) -> anyhow::Result<Candidate> {
    let text = fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let file = FrameworkFile::parse(&text)
        .with_context(|| format!("parsing {} as {FRAMEWORK_SCHEMA}", path.display()))?;
    if file.weights.is_some() {
        eprintln!(
            "note: {} carries weights; they are ignored and its edges are taken as candidates",
            path.display()
        );
    }
    Ok(file.candidate())
}

/// Runs `edgekf design`.
///
/// # Errors
/// Unreadable or malformed input, infeasible design (the message names the failed condition),
/// or output that cannot be written.
pub fn run(args: &DesignArgs) -> anyhow::Result<()> {
    let method: Method = args.method.into();
    let candidate = candidate_of(args, method)?;
    let id = edgekf_io::outdir::StudyId::new("framework", &candidate.name);
    let prep =
        edgekf_io::outdir::prepare(&args.out, &id, args.force, edgekf_io::outdir::Hint::CLI)?;
    println!(
        "designing {} ({} agents in {}-D, {} candidate links) with method {:?}",
        candidate.name,
        candidate.config.len(),
        candidate.dim,
        candidate.links.len(),
        method
    );
    let start = Instant::now();
    let mut designed = design::design(&candidate, method)
        .map_err(|e| anyhow!("design of {:?} failed — {e}", candidate.name))?;
    let elapsed = start.elapsed();
    if args.leaders == Some(LeadersArg::Auto) {
        designed.framework = choose_leaders(args, designed.framework)?;
    }
    let f = &designed.framework;
    let report = CheckReport::from_framework(f);
    println!("{report}");
    print_summary(&candidate, &designed, method, elapsed.as_secs_f64());
    report
        .verdict()
        .map_err(|e| anyhow!("the designed framework failed its checks — {e}"))?;

    let mut st = crate::interrupt::stage(&args.out)?;
    let json = edgekf_io::to_json_pretty(&FrameworkFile::from_framework(f))?;
    st.write("framework.json", json.as_bytes())?;
    let tmp = st.path("framework.png");
    plot_framework(f, &report, designed.method, &tmp)?;
    crate::commit(st, prep, &id)?;
    println!(
        "wrote {} and {}",
        args.out.join("framework.json").display(),
        args.out.join("framework.png").display()
    );
    Ok(())
}

/// The candidate of `edgekf design`: read from the input file or generated, its cost checked
/// before anything runs, with the leaders the flags ask for.
fn candidate_of(args: &DesignArgs, method: Method) -> anyhow::Result<Candidate> {
    let mut candidate = match (&args.input, args.generate) {
        (Some(path), None) => {
            let c = read_input(path)?;
            check_cost(
                &path.display().to_string(),
                c.config.len(),
                c.dim,
                c.links.len() as f64,
                design::cost::Generation::Given,
                method,
                args.max_hours,
                "thin the candidate links, or use `--method yang`",
            )?;
            c
        }
        (None, Some(which)) => {
            if let Some((links, how)) = generated_size(args, which) {
                check_cost(
                    &format!("--generate {}", format!("{which:?}").to_lowercase()),
                    args.agents,
                    args.dim,
                    links,
                    how,
                    method,
                    args.max_hours,
                    "lower `--agents`",
                )?;
            }
            generate(args, which)?
        }
        _ => bail!("give either a framework file or --generate"),
    };
    match &args.leaders {
        Some(LeadersArg::List(list)) => candidate.leaders = list.clone(),
        Some(LeadersArg::None | LeadersArg::Auto) => candidate.leaders.clear(),
        None => {}
    }
    Ok(candidate)
}

/// `--leaders auto`: the designed framework with the leaders `design::choose_leaders` picks.
fn choose_leaders(args: &DesignArgs, framework: Framework) -> anyhow::Result<Framework> {
    let mode: LeaderMode = args.leader_mode.into();
    let choice = design::choose_leaders(&framework, mode)
        .map_err(|e| anyhow!("choosing leaders failed — {e}"))?;
    println!(
        "leaders chosen ({mode:?} mode): {:?} — λ_min(L_ff) = {:.4}, proxy σ_min(V_ℓ) = {:.4}; \
         best of {} evaluated among {} candidate sets ranked by the proxy",
        choice.leaders,
        choice.follower_min_eigenvalue,
        choice.proxy,
        choice.evaluated,
        choice.candidates
    );
    framework
        .with_leaders(&choice.leaders)
        .map_err(|e| anyhow!("choosing leaders failed — {e}"))
}

/// The design's links, solver and time, one line.
fn print_summary(candidate: &Candidate, designed: &design::Design, method: Method, time: f64) {
    let f = &designed.framework;
    let kept = f.graph().links().len();
    let degree = 2.0 * kept as f64 / f.agents() as f64;
    if method == Method::Yang {
        let own = f
            .graph()
            .links()
            .iter()
            .filter(|&&(i, j)| {
                !candidate.links.contains(&(i, j)) && !candidate.links.contains(&(j, i))
            })
            .count();
        println!(
            "method yang: designed graph of {kept} links (average degree {degree:.2}; {own} of \
             them not among the {} candidates), {time:.3} s",
            designed.candidate_links
        );
    } else {
        println!(
            "method {}: {kept} of {} candidate links kept (average degree {degree:.2}); solver {}, \
             {} iterations, relative optimality gap {:.1e}; {time:.3} s",
            designed.method,
            designed.candidate_links,
            designed.solver,
            designed.newton_steps,
            designed.gap
        );
    }
    if let Some(note) = &designed.note {
        println!("note: {note}");
    }
}

/// Draws the framework with the figure toolkit: links with width ∝ |weight| (blue positive, vermillion
/// negative) and their weights written over them (on a white halo, so a thick link never hides its label),
/// agents as black dots, leaders as larger red ones, agent numbers beside them, axes in metres. 3-D frameworks
/// are drawn in their x–y projection.
fn plot_framework(
    f: &Framework,
    report: &CheckReport,
    method: &str,
    path: &Path,
) -> anyhow::Result<()> {
    use crate::figure::{Axis, Figure, Panel};
    let xy = |i: usize| -> (f64, f64) {
        let p = f.point(i);
        (p[0], if p.len() > 1 { p[1] } else { 0.0 })
    };
    let mut p = Panel::new(Axis::linear("x", "m"), Axis::linear("y", "m"));
    p.equal_aspect = true;
    p.coincide_tolerance = None;
    // Weight labels only while they stay readable.
    let label_weights = f.graph().links().len() <= 60;
    draw_links(&mut p, f, &xy, label_weights);
    agent_marks(&mut p, f, xy);
    let mut fig = Figure::single(framework_title(f, report, method), p).with_size(900, 900);
    if !label_weights {
        fig.notes.push(
            "Weights not written on the links (more than 60 links); see framework.json.".into(),
        );
    }
    let rep = fig.render(path).map_err(|e| anyhow!("plot: {e}"))?;
    for w in rep.problems() {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(())
}

/// The links as curves, width ∝ |weight|, and (`label_weights`) each weight written at the point
/// of its link (half way, or nearer an end) farthest from the agents and the labels placed so
/// far: a link through an agent would otherwise have its label on that agent.
fn draw_links(
    p: &mut crate::figure::Panel,
    f: &Framework,
    xy: &dyn Fn(usize) -> (f64, f64),
    label_weights: bool,
) {
    use crate::figure::{palette, Curve, Label, Style, VAlign};
    let n = f.agents();
    let wmax = f
        .weights()
        .iter()
        .fold(0.0_f64, |m, w| m.max(w.abs()))
        .max(f64::MIN_POSITIVE);
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for i in 0..n {
        let (x, y) = xy(i);
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let extent = (x1 - x0).max(y1 - y0).max(1e-9);
    let mut taken: Vec<(f64, f64)> = (0..n).map(xy).collect();
    for (&(i, j), &w) in f.graph().links().iter().zip(f.weights()) {
        let (a, b) = (xy(i), xy(j));
        let (colour, label) = if w > 0.0 {
            (
                palette::SERIES[0],
                "positive weight w_{ij} (width ∝ |w_{ij}|)",
            )
        } else {
            (palette::SERIES[1], "negative weight w_{ij}")
        };
        p.curves.push(
            Curve::new(label, vec![a.0, b.0], vec![a.1, b.1]).with_style(
                Style::line()
                    .colour(colour)
                    .width(1.0 + 7.0 * w.abs() / wmax),
            ),
        );
        if label_weights {
            let q = label_spot(a, b, &taken, extent);
            taken.push(q);
            p.labels.push(Label {
                size: 12.0,
                offset: (0.0, 0.0),
                v: VAlign::Middle,
                ..Label::new(q.0, q.1, format!("{w:.2}").replace('-', "−"))
            });
        }
    }
}

/// The framework figure's title: name, design, links and the stress's conditioning.
fn framework_title(f: &Framework, report: &CheckReport, method: &str) -> String {
    format!(
        "{} — {} design, {} links, λ_{{max}}/λ_{{gap}} = {:.1}{}",
        f.name(),
        method,
        f.graph().links().len(),
        report.max_eigenvalue() / report.stress_gap(),
        if f.dim() == 3 {
            " (x–y projection)"
        } else {
            ""
        }
    )
}

/// Where a link's weight label goes: half way from `a` to `b` unless that is within 6 % of the
/// extent of an agent or a placed label (`taken`); then the clearest of a few points along it.
fn label_spot(a: (f64, f64), b: (f64, f64), taken: &[(f64, f64)], extent: f64) -> (f64, f64) {
    let clearance = |q: (f64, f64)| {
        taken
            .iter()
            .map(|t| (t.0 - q.0).hypot(t.1 - q.1))
            .fold(f64::INFINITY, f64::min)
    };
    let at = |t: f64| (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
    let q = at(0.5);
    if clearance(q) >= 0.06 * extent {
        return q;
    }
    [0.5, 0.38, 0.62, 0.3, 0.7, 0.25, 0.75]
        .iter()
        .map(|&t| at(t))
        .max_by(|p, r| clearance(*p).total_cmp(&clearance(*r)))
        .unwrap_or(q)
}

/// The agents as black dots, the leaders as larger red ones, each numbered.
fn agent_marks(p: &mut crate::figure::Panel, f: &Framework, xy: impl Fn(usize) -> (f64, f64)) {
    use crate::figure::{palette, Curve, HAlign, Label, Marker, Shape, Style};
    let leaders = f.leaders();
    let (fx, fy): (Vec<f64>, Vec<f64>) = (0..f.agents())
        .filter(|i| !leaders.contains(i))
        .map(&xy)
        .unzip();
    p.curves.push(
        Curve::new("agents", fx, fy)
            .with_style(Style::markers(Marker::new(Shape::Circle, 12.0)).colour(palette::MARKER)),
    );
    if !leaders.is_empty() {
        let (lx, ly): (Vec<f64>, Vec<f64>) = leaders.iter().map(|&i| xy(i)).unzip();
        p.curves.push(
            Curve::new("leaders", lx, ly).with_style(
                Style::markers(Marker::new(Shape::Circle, 16.0)).colour(palette::LEADER),
            ),
        );
    }
    for i in 0..f.agents() {
        let (x, y) = xy(i);
        p.labels.push(Label {
            offset: (9.0, -9.0),
            h: HAlign::Left,
            size: 15.0,
            ..Label::new(x, y, format!("{i}"))
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(out: PathBuf) -> DesignArgs {
        DesignArgs {
            input: None,
            generate: Some(Generator::Hexagon),
            agents: 20,
            dim: 2,
            neighbours: 2,
            seed: 1,
            method: MethodArg::Sdp,
            leaders: None,
            leader_mode: LeaderModeArg::Clique,
            out,
            force: false,
            max_hours: crate::DEFAULT_MAX_HOURS,
        }
    }

    #[test]
    fn hexagon_round_trip_writes_file_and_picture() {
        let dir = std::env::temp_dir().join(format!("edgekf-design-{}", std::process::id()));
        let a = args(dir.clone());
        run(&a).unwrap();
        let text = fs::read_to_string(dir.join("framework.json")).unwrap();
        let file: FrameworkFile = serde_json::from_str(&text).unwrap();
        assert_eq!(file.schema, FRAMEWORK_SCHEMA);
        assert_eq!(file.edges.len(), 30);
        assert_eq!(file.weights.as_ref().unwrap().len(), 30);
        assert!(fs::metadata(dir.join("framework.png")).unwrap().len() > 1000);
        // Reading the written file back designs the same framework.
        let again = DesignArgs {
            input: Some(dir.join("framework.json")),
            generate: None,
            out: dir.join("again"),
            ..a
        };
        run(&again).unwrap();
        let file2: FrameworkFile =
            serde_json::from_str(&fs::read_to_string(dir.join("again/framework.json")).unwrap())
                .unwrap();
        assert_eq!(file2.edges, file.edges);
        // A flexible input fails with the condition named.
        let mut flex = file.clone();
        flex.edges
            .retain(|e| !(e[1] == 9 && e[0] != 4 && e[0] != 8));
        flex.weights = None;
        let flex_path = dir.join("flex.json");
        fs::write(&flex_path, serde_json::to_string(&flex).unwrap()).unwrap();
        let err = run(&DesignArgs {
            input: Some(flex_path),
            generate: None,
            out: dir.join("flex"),
            ..args(dir.clone())
        })
        .unwrap_err();
        assert!(err.to_string().contains("not universally rigid"), "{err}");
        assert!(!dir.join("flex/framework.json").exists());
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn zhao_example_and_automatic_leaders() {
        let dir = std::env::temp_dir().join(format!("edgekf-design-zhao-{}", std::process::id()));
        // Zhao's example keeps its unlinked leaders 0, 1, 2.
        let a = DesignArgs {
            generate: Some(Generator::Zhao7),
            method: MethodArg::Sparse,
            out: dir.join("zhao"),
            ..args(dir.clone())
        };
        run(&a).unwrap();
        let file: FrameworkFile =
            serde_json::from_str(&fs::read_to_string(dir.join("zhao/framework.json")).unwrap())
                .unwrap();
        assert_eq!(file.leaders, vec![0, 1, 2]);
        assert_eq!(file.edges.len(), 12);
        // --leaders auto in both modes writes D + 1 leaders; in clique mode they are linked.
        for mode in [LeaderModeArg::Clique, LeaderModeArg::Affine] {
            let out = dir.join(format!("{mode:?}"));
            run(&DesignArgs {
                generate: Some(Generator::Backbone),
                agents: 30,
                leaders: Some(LeadersArg::Auto),
                leader_mode: mode,
                out: out.clone(),
                ..args(dir.clone())
            })
            .unwrap();
            let file: FrameworkFile =
                serde_json::from_str(&fs::read_to_string(out.join("framework.json")).unwrap())
                    .unwrap();
            assert_eq!(file.leaders.len(), 3);
            if mode == LeaderModeArg::Clique {
                for (k, &i) in file.leaders.iter().enumerate() {
                    for &j in &file.leaders[k + 1..] {
                        assert!(
                            file.edges.contains(&[i.min(j), i.max(j)]),
                            "{:?}",
                            file.leaders
                        );
                    }
                }
            }
        }
        assert_eq!(
            "4, 7,9".parse::<LeadersArg>(),
            Ok(LeadersArg::List(vec![4, 7, 9]))
        );
        assert!("4;7".parse::<LeadersArg>().is_err());
        let _ = fs::remove_dir_all(&dir);
    }
}
