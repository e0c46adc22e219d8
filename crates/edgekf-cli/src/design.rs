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
use edgekf::design::{self, generators, Candidate, CheckReport, Method};
use edgekf::framework::Framework;
use plotters::prelude::*;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

/// Schema tag of framework files.
pub const FRAMEWORK_SCHEMA: &str = "edgekf.framework/1";

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
    /// Seed of the random generators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Design method.
    #[arg(long, value_enum, default_value = "sdp")]
    pub method: MethodArg,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// A framework file (`edgekf.framework/1`).
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
pub struct FrameworkFile {
    /// Must be [`FRAMEWORK_SCHEMA`].
    pub schema: String,
    /// Name.
    pub name: String,
    /// D.
    pub dim: usize,
    /// Nominal configuration, one point per agent.
    pub config: Vec<Vec<f64>>,
    /// Undirected links `[i, j]`, `i < j`, sorted (as input: the candidate links).
    pub edges: Vec<[usize; 2]>,
    /// One weight per link (absent in an input: to be designed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
    /// Leaders.
    #[serde(default)]
    pub leaders: Vec<usize>,
}

impl FrameworkFile {
    /// The file of a designed framework.
    pub fn from_framework(f: &Framework) -> Self {
        Self {
            schema: FRAMEWORK_SCHEMA.into(),
            name: f.name().into(),
            dim: f.dim(),
            config: (0..f.agents()).map(|i| f.point(i).to_vec()).collect(),
            edges: f.graph().links().iter().map(|&(i, j)| [i, j]).collect(),
            weights: Some(f.weights().to_vec()),
            leaders: f.leaders().to_vec(),
        }
    }

    /// The design input it describes.
    pub fn candidate(&self) -> Candidate {
        Candidate {
            name: self.name.clone(),
            dim: self.dim,
            config: self.config.clone(),
            links: self.edges.iter().map(|e| (e[0], e[1])).collect(),
            leaders: self.leaders.clone(),
        }
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
    let file: FrameworkFile = serde_json::from_str(&text)
        .with_context(|| format!("parsing {} as {FRAMEWORK_SCHEMA}", path.display()))?;
    if file.schema != FRAMEWORK_SCHEMA {
        bail!(
            "{}: schema is {:?}, expected {FRAMEWORK_SCHEMA:?}",
            path.display(),
            file.schema
        );
    }
    if file.weights.is_some() {
        eprintln!(
            "note: {} carries weights; they are ignored and its edges are taken as candidates",
            path.display()
        );
    }
    Ok(file.candidate())
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so a
/// reader never sees a half-written file.
fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let tmp = tmp_path(path);
    fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))
}

/// `DIR/.NAME.tmp.EXT` (the extension kept: plotters picks the image format from it).
fn tmp_path(path: &Path) -> PathBuf {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("out");
    let ext = path.extension().and_then(|s| s.to_str()).unwrap_or("tmp");
    path.with_file_name(format!(".{stem}.tmp.{ext}"))
}

/// Runs `edgekf design`.
///
/// # Errors
/// Unreadable or malformed input, infeasible design (the message names the failed condition),
/// or output that cannot be written.
pub fn run(args: &DesignArgs) -> anyhow::Result<()> {
    let candidate = match (&args.input, args.generate) {
        (Some(path), None) => read_input(path)?,
        (None, Some(which)) => generate(args, which)?,
        _ => bail!("give either a framework file or --generate"),
    };
    let method: Method = args.method.into();
    println!(
        "designing {} ({} agents in {}-D, {} candidate links) with method {:?}",
        candidate.name,
        candidate.config.len(),
        candidate.dim,
        candidate.links.len(),
        method
    );
    let start = Instant::now();
    let designed = design::design(&candidate, method)
        .map_err(|e| anyhow!("design of {:?} failed — {e}", candidate.name))?;
    let elapsed = start.elapsed();
    let f = &designed.framework;
    let report = CheckReport::from_framework(f);
    println!("{report}");
    let kept = f.graph().links().len();
    let degree = 2.0 * kept as f64 / f.agents() as f64;
    let time = elapsed.as_secs_f64();
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
            "method {}: {kept} of {} candidate links kept (average degree {degree:.2}), {} Newton \
             steps, {time:.3} s",
            designed.method, designed.candidate_links, designed.newton_steps
        );
    }
    report
        .verdict()
        .map_err(|e| anyhow!("the designed framework failed its checks — {e}"))?;

    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&FrameworkFile::from_framework(f))?;
    let json_path = args.out.join("framework.json");
    write_atomic(&json_path, json.as_bytes())?;
    let png_path = args.out.join("framework.png");
    let tmp = tmp_path(&png_path);
    plot_framework(f, &report, designed.method, &tmp)?;
    fs::rename(&tmp, &png_path).with_context(|| format!("renaming to {}", png_path.display()))?;
    println!("wrote {} and {}", json_path.display(), png_path.display());
    Ok(())
}

/// Draws agents, links (width ∝ |weight|, blue positive, red negative), leaders highlighted.
/// 3-D frameworks are drawn in their x–y projection.
fn plot_framework(
    f: &Framework,
    report: &CheckReport,
    method: &str,
    path: &Path,
) -> anyhow::Result<()> {
    crate::plot::register_fonts();
    let n = f.agents();
    let xy = |i: usize| -> (f64, f64) {
        let p = f.point(i);
        (p[0], if p.len() > 1 { p[1] } else { 0.0 })
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for i in 0..n {
        let (x, y) = xy(i);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let pad = 0.08 * (x1 - x0).max(y1 - y0).max(1e-9);
    let root = crate::figure::backend::KernedText::new(BitMapBackend::new(path, (900, 900)))
        .into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
    let title = format!(
        "{} — {} design, {} links, λ_max/λ_gap = {:.1}{}",
        f.name(),
        method,
        f.graph().links().len(),
        report.max_eigenvalue() / report.stress_gap(),
        if f.dim() == 3 {
            " (x–y projection)"
        } else {
            ""
        }
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(x0 - pad..x1 + pad, y0 - pad..y1 + pad)
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .configure_mesh()
        .x_desc("x")
        .y_desc("y")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    let wmax = f
        .weights()
        .iter()
        .fold(0.0_f64, |m, w| m.max(w.abs()))
        .max(f64::MIN_POSITIVE);
    for (&(i, j), &w) in f.graph().links().iter().zip(f.weights()) {
        let width = 1 + (7.0 * w.abs() / wmax).round() as u32;
        let colour = if w > 0.0 { BLUE.mix(0.7) } else { RED.mix(0.6) };
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![xy(i), xy(j)],
                colour.stroke_width(width),
            )))
            .map_err(|e| anyhow!("plot: {e}"))?;
    }
    let leaders = f.leaders();
    chart
        .draw_series((0..n).map(|i| {
            let leader = leaders.contains(&i);
            let style = if leader {
                ShapeStyle::from(&BLACK).filled()
            } else {
                ShapeStyle::from(&RGBColor(90, 90, 90)).filled()
            };
            Circle::new(xy(i), if leader { 9 } else { 6 }, style)
        }))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("agents (large: leaders)")
        .legend(|(x, y)| Circle::new((x, y), 6, ShapeStyle::from(&BLACK).filled()));
    chart
        .draw_series((0..n).map(|i| {
            Text::new(
                format!("{i}"),
                (xy(i).0 + 0.25 * pad, xy(i).1 + 0.25 * pad),
                ("sans-serif", 14).into_font(),
            )
        }))
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("positive weight (width ∝ |w|)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(3)));
    chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("negative weight")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(3)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    root.present().map_err(|e| anyhow!("plot: {e}"))?;
    Ok(())
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
            seed: 1,
            method: MethodArg::Sdp,
            out,
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
}
