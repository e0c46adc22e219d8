//! `edgekf claims [NAME…] [--seeds S] [--json] [--out DIR]`: the papers' claims checked on the
//! reproductions (the `edgekf-claims` registry), as a table, JSON, or files for the report page.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use edgekf::sim::Observer;
use edgekf_claims::rule::num;
use edgekf_claims::{Hooks, Options, Outcome, Paper, Study, Verdict};

use crate::{positive, Progress};

/// Arguments of `edgekf claims`.
#[derive(Args, Debug)]
pub struct ClaimsArgs {
    /// Reproductions whose claims to check (`edgekf reproduce --list`); none or `all`: every
    /// claim.
    pub names: Vec<String>,
    /// Seeds per simulation (default: each simulation's own, 1 to 6); statistics over seeds
    /// need 2 or more.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub seeds: Option<usize>,
    /// Print a JSON array with the keys id, paper, where, claim, paper_value, value, se, verdict.
    #[arg(long)]
    pub json: bool,
    /// Write DIR/claims.json and DIR/claims.md (every claim checked) and, into each simulation's
    /// directory that `reproduce --out DIR` wrote, DIR/<simulation>/claims.json (for its report
    /// page). DIR must not be a study's own directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, allow_negative_numbers = true, value_parser = positive)]
    pub threads: Option<usize>,
}

struct CliHooks {
    bar: Progress,
    started: Mutex<Option<Instant>>,
}

impl Hooks for CliHooks {
    fn observer(&self) -> &dyn Observer {
        &self.bar
    }

    fn study_start(&self, _study: &Study) {
        if let Ok(mut s) = self.started.lock() {
            *s = Some(Instant::now());
        }
    }

    fn study_done(&self, study: &Study) {
        let t = self
            .started
            .lock()
            .ok()
            .and_then(|s| *s)
            .map_or(0.0, |s| s.elapsed().as_secs_f64());
        self.bar.0.suspend(|| {
            eprintln!(
                "  {:<16} {:>6.1} s  {}",
                study.id,
                t,
                if study.about.is_empty() {
                    "the shipped scenario"
                } else {
                    study.about
                }
            );
        });
    }
}

/// Runs `edgekf claims`.
pub fn run(args: &ClaimsArgs) -> Result<()> {
    let claims = edgekf_claims::select(&args.names)?;
    let opt = Options {
        seeds: args.seeds,
        ..Options::default()
    };
    // Where the files go is checked before the simulations run, not after.
    let beside = match &args.out {
        Some(dir) => study_dirs(dir, &claims)?,
        None => BTreeMap::new(),
    };
    let studies = edgekf_claims::needed_studies(&claims)?;
    let total: u64 = studies.iter().map(|s| s.work(opt.size, opt.seeds)).sum();
    let pool = crate::pool(args.threads)?;
    let hooks = CliHooks {
        bar: Progress::new(total.max(1), "claims"),
        started: Mutex::new(None),
    };
    let start = Instant::now();
    eprintln!(
        "checking {} claim(s) on {} simulation(s) on {} thread(s):",
        claims.len(),
        studies.len(),
        pool.current_num_threads()
    );
    let outcomes = pool.install(|| edgekf_claims::evaluate(&claims, opt, &hooks))?;
    hooks.bar.0.finish_and_clear();
    eprintln!("done in {:.1} s", start.elapsed().as_secs_f64());
    if args.json {
        println!("{}", json(&outcomes)?);
    } else {
        print!("{}", table(&outcomes));
    }
    if let Some(dir) = &args.out {
        write_out(dir, &outcomes, &beside)?;
        eprintln!("wrote {}", dir.join("claims.json").display());
    }
    Ok(())
}

/// The simulations of `claims` whose directory in `dir` holds that simulation's study (as
/// `reproduce --out DIR` writes it): whether each gets its `claims.json`. Refused before any
/// simulation runs: `dir` not a directory or a study's own directory, or a simulation's
/// directory holding something else — the claims of one study must not land among another's
/// files. A simulation without a directory (or with an empty one) gets none, which is said: a
/// directory holding only `claims.json` would be refused by a later `reproduce`.
fn study_dirs(dir: &Path, claims: &[edgekf_claims::Claim]) -> Result<BTreeMap<&'static str, bool>> {
    use edgekf_io::outdir;
    if dir.exists() && !dir.is_dir() {
        bail!(
            "{}: exists and is not a directory; choose another --out",
            dir.display()
        );
    }
    if let Some(what) = outdir::held(dir) {
        bail!(
            "{}: holds {what}, not the output of `edgekf reproduce`; `claims --out` writes \
             claims.json and claims.md there and each simulation's claims.json into its \
             directory: give the directory `reproduce --out` wrote, or a new one",
            dir.display()
        );
    }
    let mut beside = BTreeMap::new();
    for c in claims {
        let sim = edgekf_claims::simulation_of(c);
        if !beside.contains_key(sim) {
            beside.insert(sim, holds_simulation(dir, c)?);
        }
    }
    let missing: Vec<&str> = beside
        .iter()
        .filter(|(_, &b)| !b)
        .map(|(s, _)| *s)
        .collect();
    if !missing.is_empty() {
        eprintln!(
            "note: {} has no directory of {} (`edgekf reproduce … --out {}` writes them): their \
             claims go to claims.json and claims.md only",
            dir.display(),
            missing.join(", "),
            dir.display()
        );
    }
    Ok(beside)
}

/// Whether `dir`'s directory of the simulation of claim `c` holds that simulation's study
/// ([`edgekf_io::outdir::holds`]); refused when it holds anything else.
fn holds_simulation(dir: &Path, c: &edgekf_claims::Claim) -> Result<bool> {
    let sim = edgekf_claims::simulation_of(c);
    let slam = edgekf_io::reproductions::find(c.reproduction).is_some_and(|e| e.is_slam());
    let id = edgekf_io::outdir::StudyId::new(if slam { "slam" } else { "study" }, sim);
    edgekf_io::outdir::holds(&dir.join(sim), &id).map_err(|m| {
        anyhow::anyhow!(
            "{m}: its claims.json would mix with them; give the directory `reproduce --out` \
             wrote, or a new one"
        )
    })
}

fn json(outcomes: &[Outcome]) -> Result<String> {
    let records: Vec<_> = outcomes.iter().map(Outcome::record).collect();
    serde_json::to_string_pretty(&records).context("cannot serialise the claims")
}

fn write_out(dir: &Path, outcomes: &[Outcome], beside: &BTreeMap<&str, bool>) -> Result<()> {
    let mut st = crate::interrupt::stage(dir)?;
    let mut text = json(outcomes)?;
    text.push('\n');
    st.write("claims.json", text.as_bytes())?;
    st.write("claims.md", markdown(outcomes).as_bytes())?;
    crate::interrupt::critical(&dir.join("claims.json"), || Ok(st.commit()?))?;
    let mut by_sim: BTreeMap<&str, Vec<Outcome>> = BTreeMap::new();
    for o in outcomes {
        by_sim
            .entry(edgekf_claims::simulation_of(&o.claim))
            .or_default()
            .push(o.clone());
    }
    for (sim, list) in by_sim {
        // Checked again: the directory may have changed while the simulations ran.
        if !beside.get(sim).copied().unwrap_or(false) || !holds_simulation(dir, &list[0].claim)? {
            continue;
        }
        let mut st = crate::interrupt::stage(&dir.join(sim))?;
        let mut text = json(&list)?;
        text.push('\n');
        st.write("claims.json", text.as_bytes())?;
        crate::interrupt::critical(&dir.join(sim).join("claims.json"), || Ok(st.commit()?))?;
    }
    Ok(())
}

/// `value ± se`, `value (exact)`, or `—`.
fn ours(o: &Outcome) -> String {
    match o.estimate {
        Some(e) if e.value.is_finite() => {
            if e.se == 0.0 {
                format!("{} (exact)", num(e.value))
            } else if e.se.is_nan() {
                format!("{} (no SE)", num(e.value))
            } else {
                format!("{} ± {}", num(e.value), num(e.se))
            }
        }
        _ => "—".into(),
    }
}

fn counts(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    let count = |list: &[&Outcome], v: Verdict| list.iter().filter(|o| o.verdict == v).count();
    let all: Vec<&Outcome> = outcomes.iter().collect();
    let _ = write!(
        s,
        "{} claims: {} agree, {} differ, {} not checkable",
        all.len(),
        count(&all, Verdict::Agrees),
        count(&all, Verdict::Differs),
        count(&all, Verdict::NotCheckable)
    );
    let mut papers: Vec<Paper> = outcomes.iter().map(|o| o.claim.paper).collect();
    papers.sort();
    papers.dedup();
    let parts: Vec<String> = papers
        .iter()
        .map(|p| {
            let list: Vec<&Outcome> = outcomes.iter().filter(|o| o.claim.paper == *p).collect();
            format!(
                "{} {}/{}/{}",
                p.name(),
                count(&list, Verdict::Agrees),
                count(&list, Verdict::Differs),
                count(&list, Verdict::NotCheckable)
            )
        })
        .collect();
    let _ = write!(s, " (agree/differ/not checkable: {})", parts.join("; "));
    s
}

fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// The table on the terminal (Markdown, so it pastes into documents).
fn table(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| id | paper, where | claim | paper's value | ours ± SE | verdict |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for o in outcomes {
        let c = &o.claim;
        let _ = writeln!(
            s,
            "| `{}` | {}, {} | {} | {} | {} | {} |",
            c.id,
            c.paper.name(),
            cell(c.location),
            cell(c.statement),
            cell(c.paper_value),
            ours(o),
            o.verdict
        );
    }
    let notes: Vec<&Outcome> = outcomes
        .iter()
        .filter(|o| o.note.is_some() || o.reason.is_some())
        .collect();
    if !notes.is_empty() {
        let _ = writeln!(s, "\nNotes:");
        for o in notes {
            let text = o
                .reason
                .as_deref()
                .or(o.note.as_deref())
                .unwrap_or_default();
            let _ = writeln!(s, "- `{}`: {text}", o.claim.id);
        }
    }
    let _ = writeln!(s, "\n{}", counts(outcomes));
    s
}

/// `claims.md`: every claim with how it is measured and its rule (`docs/claims.md` is this
/// file from a full run).
fn markdown(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# The papers' claims, checked\n\nGenerated by `edgekf claims --out DIR` (`DIR/claims.md`); \
         {}.\n\nEach claim is measured on a simulation (a shipped reproduction, possibly edited: \
         the study named in the last column) with the statistic given there, and judged by its \
         rule: an ordering agrees when it holds by more than 3 standard errors, an approximate \
         number when the whole interval value ± 3 SE lies inside the stated tolerance; anything \
         else differs. Exact quantities (SE 0) compare exactly.\n",
        counts(outcomes)
    );
    let mut papers: Vec<Paper> = outcomes.iter().map(|o| o.claim.paper).collect();
    papers.sort();
    papers.dedup();
    for p in papers {
        let _ = writeln!(s, "## {}\n", p.name());
        let _ = writeln!(
            s,
            "| id | where | claim | paper's value | ours ± SE | verdict | measured as · rule |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        for o in outcomes.iter().filter(|o| o.claim.paper == p) {
            let c = &o.claim;
            let mut how = format!("{} · {}", c.measure.describe(), c.rule.describe());
            if let Some(n) = o.note.as_deref().or(o.reason.as_deref()) {
                let _ = write!(how, " · {n}");
            }
            let _ = writeln!(
                s,
                "| `{}` | {} | {} | {} | {} | {} | {} |",
                c.id,
                cell(c.location),
                cell(c.statement),
                cell(c.paper_value),
                ours(o),
                o.verdict,
                cell(&how)
            );
        }
        let _ = writeln!(s);
    }
    s
}
