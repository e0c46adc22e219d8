//! The whole-program fuzz of issue 16 point 3: mutated scenario files, resolved `scenario.json`
//! files and framework files, each run through the `edgekf` binary exactly as a user runs it
//! (`edgekf run FILE --out DIR`), at tiny size and with a wall-clock limit per case.
//!
//! - **Seeds**: every shipped `scenarios/*.toml` (the filter scenarios and the SLAM ones); the
//!   resolved `scenario.json` of each filter scenario (`Scenario::to_resolved`) and of each SLAM
//!   scenario (written by the binary itself); framework files as `edgekf design` writes them, run
//!   through a scenario that names them in `framework.file`.
//! - **Size**: `--runs 2 --steps 30`, except that a case whose mutation touched `steps`, `every`
//!   or `[sim]` keeps the file's own steps; one case in four adds `--threads 1`, one in ten
//!   `--allow-divergence`; SLAM scenarios take no size flags (their horizon is in the file).
//!   `--max-hours` is set so low (0.36 s) that a study the cost estimate calls long is refused:
//!   a case that is accepted and still runs past the time limit is a hang, not a big study. The
//!   limit is on the process's CPU time (a spinning process burns CPU; a starved one on a busy
//!   machine does not), with a wall-clock safety net of six times the limit.
//! - **Defects**: a panic (exit 101 or "panicked" on stderr), a crash (killed by a signal, e.g.
//!   an allocation failure), a hang (past the time limit), exit 0 with non-finite numbers in
//!   `metrics.csv` (or in `paths.csv`, `robots.csv`, `team.csv`), exit 0 while `status.csv`
//!   reports a divergence that was not allowed, exit 3 without a divergence in `status.csv`, a
//!   non-zero exit without a message on stderr, output left behind after exit 1/2 (any file, or
//!   the directory itself), a temporary file left after success, an output file that does not
//!   parse (CSV, JSON, PNG), an unknown exit code; and, for one successful filter case in twenty,
//!   a re-run of its `scenario.json` that does not reproduce `metrics.csv` byte for byte.

#![allow(dead_code)]

#[path = "../../../edgekf/tests/fuzz_common/mutate.rs"]
pub mod mutate;

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use edgekf::scenario::Scenario;
use mutate::{Format, Mutator, Seed};

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_edgekf");

/// What a seed is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A filter scenario (TOML).
    Toml,
    /// A resolved filter scenario (`edgekf.scenario/1`).
    Resolved,
    /// A SLAM scenario (TOML or resolved `edgekf.slam/1`).
    Slam,
    /// A framework file, run through [`FRAMEWORK_SCENARIO`].
    Framework,
}

/// The scenario that reads a fuzzed framework file (with a figure of each kind).
pub const FRAMEWORK_SCENARIO: &str = r#"
name = "framework-file"
estimators = ["mle", "rkf", "jrkf", "crkf"]
[framework]
file = "framework.json"
[sim]
steps = 30
runs = 2
[[plots]]
file = "error"
kind = "metric"
metric = "est_error"
log_y = true
[[plots]]
file = "paths"
kind = "paths"
"#;

/// The repository's `scenarios/` directory.
pub fn scenarios_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

/// Seeds and their roles. `work` is a scratch directory (the SLAM resolved seeds are written by
/// the binary there).
pub fn corpus(base: u64, work: &Path) -> (Mutator, Vec<Role>) {
    let mut seeds = Vec::new();
    let mut roles = Vec::new();
    let mut files: Vec<PathBuf> = fs::read_dir(scenarios_dir())
        .expect("scenarios directory")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    for p in &files {
        let text = fs::read_to_string(p).expect("readable");
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        match edgekf_io::spec_from_toml(&text) {
            Ok(spec) => {
                // A scenario naming a framework file (the GA-RKF ones) is a seed in its
                // resolved form only: a mutated copy elsewhere would not find the file.
                let file = spec.framework.file.as_ref().map(|f| {
                    let text = fs::read_to_string(scenarios_dir().join(f)).expect("framework file");
                    edgekf_io::framework::spec_from_json(&text).expect("framework file")
                });
                let sc = Scenario::from_spec(&spec, file.as_ref()).expect("valid shipped scenario");
                if file.is_none() {
                    seeds.push(Seed::new(&name, Format::Toml, &text).expect("seed"));
                    roles.push(Role::Toml);
                }
                let json = serde_json::to_string_pretty(&sc.to_resolved()).expect("json");
                seeds.push(
                    Seed::new(&name.replace(".toml", ".json"), Format::Json, &json).expect("seed"),
                );
                roles.push(Role::Resolved);
            }
            Err(_) => {
                seeds.push(Seed::new(&name, Format::Toml, &text).expect("seed"));
                roles.push(Role::Slam);
                let out = work.join(format!("seed-{name}"));
                let o = Command::new(BIN)
                    .args(["run", p.to_str().unwrap(), "--out", out.to_str().unwrap()])
                    .output()
                    .expect("runs");
                assert!(
                    o.status.success(),
                    "{name}: {}",
                    String::from_utf8_lossy(&o.stderr)
                );
                let json = fs::read_to_string(out.join("scenario.json")).expect("resolved");
                seeds.push(
                    Seed::new(&name.replace(".toml", ".json"), Format::Json, &json).expect("seed"),
                );
                roles.push(Role::Slam);
                let _ = fs::remove_dir_all(&out);
            }
        }
    }
    for (name, fw) in frameworks(work) {
        seeds.push(Seed::new(&name, Format::Json, &fw).expect("seed"));
        roles.push(Role::Framework);
    }
    (Mutator::new(seeds, base), roles)
}

/// Framework files written by `edgekf design --generate … --method …`.
fn frameworks(work: &Path) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (gen, method) in [
        ("hexagon", "sdp"),
        ("hexagon3d", "sdp"),
        ("hexagon", "yang"),
    ] {
        let dir = work.join(format!("design-{gen}-{method}"));
        let o = Command::new(BIN)
            .args(["design", "--generate", gen, "--method", method, "--out"])
            .arg(&dir)
            .output()
            .expect("runs");
        assert!(
            o.status.success(),
            "design {gen} {method}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let text = fs::read_to_string(dir.join("framework.json")).expect("framework.json");
        out.push((format!("framework:{gen}-{method}"), text));
        let _ = fs::remove_dir_all(&dir);
    }
    out
}

/// Settings of a fuzz run.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Per-case wall-clock limit.
    pub limit: Duration,
    /// `--max-hours` passed to every filter case.
    pub max_hours: f64,
    /// Worker threads (each runs one binary at a time).
    pub workers: usize,
    /// Where failing cases are kept (input, flags, stderr).
    pub keep: PathBuf,
    /// Scratch directory.
    pub work: PathBuf,
}

/// How a case ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Exit 0, outputs sound.
    Ran,
    /// Exit 1 or 2 with a message and nothing left behind.
    Refused,
    /// Exit 3 with the divergence in `status.csv`.
    Diverged,
    /// A defect of this kind, with detail.
    Defect(String, String),
}

/// The flags of case `n`.
pub fn flags(case: &mutate::Case, role: Role, max_hours: f64) -> Vec<String> {
    if role == Role::Slam {
        return Vec::new();
    }
    let mut f = vec!["--runs".to_string(), "2".to_string()];
    if !case.touches_size {
        f.extend(["--steps".to_string(), "30".to_string()]);
    }
    if case.number % 4 == 1 {
        f.extend(["--threads".to_string(), "1".to_string()]);
    }
    if case.number % 10 == 3 {
        f.push("--allow-divergence".to_string());
    }
    f.extend(["--max-hours".to_string(), format!("{max_hours}")]);
    f
}

/// Writes the case's input files into `dir`; returns the path to run.
pub fn write_input(dir: &Path, role: Role, text: &str) -> PathBuf {
    fs::create_dir_all(dir).expect("case dir");
    match role {
        Role::Framework => {
            fs::write(dir.join("framework.json"), text).expect("write");
            let p = dir.join("scenario.toml");
            fs::write(&p, FRAMEWORK_SCENARIO).expect("write");
            p
        }
        _ => {
            let p = dir.join(if text.trim_start().starts_with('{') {
                "scenario.json"
            } else {
                "scenario.toml"
            });
            fs::write(&p, text).expect("write");
            p
        }
    }
}

/// CPU time (user + system, all threads) of a running process, from `/proc/PID/stat` (Linux;
/// `None` elsewhere or once it has exited).
fn cpu_time(pid: u32) -> Option<Duration> {
    let s = fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = s.get(s.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    // After the command name: state is field 3; utime and stime are fields 14 and 15, in
    // clock ticks of 1/100 s (Linux's USER_HZ).
    let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 10))
}

/// Runs the binary with a time limit on its CPU time (so that a machine busy with other work
/// does not turn a slow case into a "hang"; a spinning process burns CPU) and a wall-clock
/// safety net of six times the limit. Returns (exit code, or None when killed or signalled;
/// whether it was killed for time; stderr; wall time).
pub fn run_binary(
    args: &[String],
    dir: &Path,
    limit: Duration,
) -> (Option<i32>, bool, String, Duration) {
    let err_path = dir.join("stderr.txt");
    let out_path = dir.join("stdout.txt");
    let start = Instant::now();
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(fs::File::create(&out_path).expect("stdout file"))
        .stderr(fs::File::create(&err_path).expect("stderr file"))
        .spawn()
        .expect("spawn edgekf");
    let pid = child.id();
    let mut wait = Duration::from_millis(1);
    let (code, timed_out) = loop {
        match child.try_wait().expect("wait") {
            Some(status) => break (status.code(), false),
            None => {
                let wall = start.elapsed();
                let cpu = cpu_time(pid).unwrap_or(wall);
                if cpu > limit || wall > 6 * limit {
                    let _ = child.kill();
                    let _ = child.wait();
                    break (None, true);
                }
                std::thread::sleep(wait);
                wait = (wait * 2).min(Duration::from_millis(20));
            }
        }
    };
    let elapsed = start.elapsed();
    let stderr = fs::read_to_string(&err_path).unwrap_or_default();
    (code, timed_out, stderr, elapsed)
}

/// Files (recursively) under `dir`.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(rd) = fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(files_under(&p));
            } else {
                out.push(p);
            }
        }
    }
    out
}

/// Checks a CSV file: the header, and that every value in the numeric columns parses as a
/// number; returns the rows and whether every number is finite.
fn csv(
    path: &Path,
    header: &str,
    numeric_from: usize,
    skip: &[usize],
) -> Result<(Vec<Vec<String>>, bool), String> {
    let text = fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let h = lines.next().unwrap_or_default();
    if !h.starts_with(header) {
        return Err(format!("{}: header `{h}`", path.display()));
    }
    let width = h.split(',').count();
    let mut rows = Vec::new();
    let mut finite = true;
    for (k, line) in lines.enumerate() {
        let f: Vec<String> = split_csv(line);
        if f.len() != width {
            return Err(format!(
                "{}: row {} has {} fields, header {width}: {line}",
                path.display(),
                k + 2,
                f.len()
            ));
        }
        for (c, v) in f.iter().enumerate().skip(numeric_from) {
            if skip.contains(&c) {
                continue;
            }
            let x: f64 = v.parse().map_err(|_| {
                format!(
                    "{}: row {} column {c}: `{v}` is not a number",
                    path.display(),
                    k + 2
                )
            })?;
            if !x.is_finite() {
                finite = false;
            }
        }
        rows.push(f);
    }
    Ok((rows, finite))
}

/// Splits one CSV line (double-quoted fields may hold commas).
fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(std::mem::take(&mut cur)),
            other => cur.push(other),
        }
    }
    out.push(cur);
    out
}

fn png_ok(path: &Path) -> bool {
    match fs::read(path) {
        Ok(b) => {
            b.len() > 20
                && b.starts_with(b"\x89PNG\r\n\x1a\n")
                && b.ends_with(&[0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82])
        }
        Err(_) => false,
    }
}

/// A finding about a run's outputs: its kind and the detail.
type Finding = (String, String);

fn finding<T>(kind: &str, detail: String) -> Result<T, Finding> {
    Err((kind.to_string(), detail))
}

/// Checks the outputs of a successful (exit 0) or diverged (exit 3) run.
fn check_outputs(out: &Path, slam: bool, code: i32, allowed_flag: bool) -> Result<(), Finding> {
    let sj = check_files(out)?;
    if slam {
        return check_slam(out, &sj);
    }
    if sj.get("schema").and_then(|s| s.as_str()) != Some("edgekf.scenario/1") {
        return finding("unparsable output", "scenario.json schema".into());
    }
    let allowed =
        allowed_flag || sj.get("allow_divergence").and_then(|v| v.as_bool()) == Some(true);
    let diverged = check_tables(out)?;
    match code {
        0 if !diverged.is_empty() && !allowed => finding(
            "exit 0 with a divergence",
            format!("status.csv: {}", diverged[0].join(",")),
        ),
        3 if diverged.is_empty() => finding(
            "exit 3 without a divergence",
            "status.csv all completed".into(),
        ),
        3 if allowed => finding("exit 3 although divergence was allowed", String::new()),
        _ => Ok(()),
    }
}

/// Every run's outputs: no temporary file left, whole PNGs, and `scenario.json` (returned).
fn check_files(out: &Path) -> Result<serde_json::Value, Finding> {
    let files = files_under(out);
    if let Some(t) = files.iter().find(|p| {
        p.file_name()
            .is_some_and(|n| n.to_string_lossy().contains(".tmp"))
    }) {
        return finding("temp file left", t.display().to_string());
    }
    let Some(sj) = fs::read_to_string(out.join("scenario.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
    else {
        return finding(
            "unparsable output",
            "scenario.json missing or not JSON".into(),
        );
    };
    for p in files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
    {
        if !png_ok(p) {
            return finding(
                "unparsable output",
                format!("{} is not a whole PNG", p.display()),
            );
        }
    }
    Ok(sj)
}

/// A SLAM run's outputs: its schema, `robots.csv` and `team.csv` whole and finite.
fn check_slam(out: &Path, sj: &serde_json::Value) -> Result<(), Finding> {
    if sj.get("schema").and_then(|s| s.as_str()) != Some("edgekf.slam/1") {
        return finding("unparsable output", "SLAM scenario.json schema".into());
    }
    for (f, h) in [
        ("robots.csv", "time,robot,quantity,value"),
        ("team.csv", "time,quantity,value"),
    ] {
        let skip: &[usize] = if f == "robots.csv" { &[2] } else { &[1] };
        match csv(&out.join(f), h, 0, skip) {
            Err(e) => return finding("unparsable output", e),
            Ok((_, false)) => {
                return finding("non-finite output, exit 0", format!("{f} has NaN/inf"))
            }
            Ok(_) => {}
        }
    }
    Ok(())
}

/// A filter run's tables: `metrics.csv` whole and finite, `status.csv` with known statuses,
/// `paths.csv` finite unless a run diverged. Returns the diverged rows of `status.csv`.
fn check_tables(out: &Path) -> Result<Vec<Vec<String>>, Finding> {
    let unparsable = |e| finding("unparsable output", e);
    let metrics = csv(
        &out.join("metrics.csv"),
        "estimator,step,time,metric,mean,std",
        1,
        &[3],
    )
    .or_else(unparsable)?;
    let (status, _) = csv(
        &out.join("status.csv"),
        "estimator,status,step,time,run,cause",
        99,
        &[],
    )
    .or_else(unparsable)?;
    if status
        .iter()
        .any(|r| r[1] != "diverged" && r[1] != "completed")
    {
        return finding("unparsable output", "status.csv: unknown status".into());
    }
    let diverged: Vec<Vec<String>> = status.into_iter().filter(|r| r[1] == "diverged").collect();
    if !metrics.1 {
        return finding(
            "non-finite output, exit 0",
            "metrics.csv has NaN/inf".into(),
        );
    }
    let paths =
        csv(&out.join("paths.csv"), "estimator,step,time,agent", 1, &[]).or_else(unparsable)?;
    if !paths.1 && diverged.is_empty() {
        return finding(
            "non-finite output, exit 0",
            "paths.csv has NaN/inf without a divergence".into(),
        );
    }
    Ok(diverged)
}

/// Runs case `n` in `dir` and judges it.
pub fn judge(m: &Mutator, roles: &[Role], n: u64, s: &Settings, dir: &Path) -> (Verdict, Duration) {
    let case = m.case(n);
    let role = roles[case.seed];
    let input = write_input(dir, role, &case.text);
    let fl = flags(&case, role, s.max_hours);
    let round_trip = role != Role::Slam && n % 20 == 7;
    let (v, stderr, wall, args) = run_input(
        &input,
        &fl,
        role == Role::Slam,
        dir,
        s.limit,
        round_trip.then_some(s.max_hours),
    );
    if let Verdict::Defect(kind, detail) = &v {
        keep(s, n, &case, role, &args, kind, detail, &stderr);
    }
    (v, wall)
}

/// Runs `edgekf run INPUT --out DIR/out FLAGS` and judges the exit, stderr and outputs; with
/// `round_trip`, a successful filter run is re-run from its `scenario.json` (with that
/// `--max-hours`). Returns the verdict, stderr, the wall time and the arguments.
pub fn run_input(
    input: &Path,
    flags: &[String],
    slam: bool,
    dir: &Path,
    limit: Duration,
    round_trip: Option<f64>,
) -> (Verdict, String, Duration, Vec<String>) {
    let out = dir.join("out");
    let mut args = vec![
        "run".to_string(),
        input.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    let allowed_flag = flags.iter().any(|f| f == "--allow-divergence");
    args.extend(flags.iter().cloned());
    let (code, timed_out, stderr, wall) = run_binary(&args, dir, limit);
    let v = if timed_out {
        Verdict::Defect(
            "hang".into(),
            format!("no exit within {limit:?} of CPU time ({wall:.1?} wall)"),
        )
    } else if stderr.contains("panicked") || code == Some(101) {
        let line = stderr
            .lines()
            .find(|l| l.contains("panicked"))
            .unwrap_or("")
            .to_string();
        Verdict::Defect("panic".into(), line)
    } else {
        match code {
            None => Verdict::Defect(
                "crash (signal)".into(),
                stderr.lines().last().unwrap_or("").to_string(),
            ),
            Some(c @ (1 | 2)) => judge_refusal(&out, &stderr, c),
            Some(c @ (0 | 3)) => {
                if c == 3 && stderr.trim().is_empty() {
                    Verdict::Defect("exit without a message".into(), "exit 3".into())
                } else {
                    match check_outputs(&out, slam, c, allowed_flag) {
                        Err((k, d)) => Verdict::Defect(k, d),
                        Ok(()) if c == 3 => Verdict::Diverged,
                        Ok(()) => match round_trip {
                            Some(h) if !slam => self::round_trip(dir, &out, limit, h),
                            _ => Verdict::Ran,
                        },
                    }
                }
            }
            Some(c) => Verdict::Defect(
                "unexpected exit code".into(),
                format!("{c}: {}", stderr.trim()),
            ),
        }
    };
    (v, stderr, wall, args)
}

/// A refusal (exit `c`, 1 or 2) says why and leaves no output behind.
fn judge_refusal(out: &Path, stderr: &str, c: i32) -> Verdict {
    let left = files_under(out);
    if stderr.trim().is_empty() {
        Verdict::Defect("exit without a message".into(), format!("exit {c}"))
    } else if !left.is_empty() {
        Verdict::Defect(
            "output left after failure".into(),
            format!(
                "{} file(s), e.g. {}; stderr: {}",
                left.len(),
                left[0].display(),
                stderr.trim()
            ),
        )
    } else if out.exists() {
        Verdict::Defect(
            "output directory left after failure".into(),
            stderr.trim().to_string(),
        )
    } else {
        Verdict::Refused
    }
}

/// Re-runs the resolved `scenario.json` of a successful run: `metrics.csv` must be identical.
fn round_trip(dir: &Path, out: &Path, limit: Duration, max_hours: f64) -> Verdict {
    let out2 = dir.join("out2");
    let args = vec![
        "run".to_string(),
        out.join("scenario.json").display().to_string(),
        "--out".into(),
        out2.display().to_string(),
        "--max-hours".into(),
        format!("{max_hours}"),
    ];
    let (code, timed_out, stderr, _) = run_binary(&args, dir, limit);
    if timed_out {
        return Verdict::Defect("hang".into(), "re-running scenario.json".into());
    }
    match code {
        Some(0) => {
            let a = fs::read(out.join("metrics.csv")).unwrap_or_default();
            let b = fs::read(out2.join("metrics.csv")).unwrap_or_default();
            if a == b {
                Verdict::Ran
            } else {
                Verdict::Defect(
                    "round trip differs".into(),
                    "metrics.csv of scenario.json differs".into(),
                )
            }
        }
        other => Verdict::Defect(
            "round trip refused".into(),
            format!(
                "scenario.json of a successful run: exit {other:?}: {}",
                stderr.trim()
            ),
        ),
    }
}

#[allow(clippy::too_many_arguments)]
fn keep(
    s: &Settings,
    n: u64,
    case: &mutate::Case,
    role: Role,
    args: &[String],
    kind: &str,
    detail: &str,
    stderr: &str,
) {
    let dir = s
        .keep
        .join(format!("{}-{n}", kind.replace([' ', '/', ','], "_")));
    let _ = fs::create_dir_all(&dir);
    let name = match role {
        Role::Framework => "framework.json",
        _ if case.text.trim_start().starts_with('{') => "scenario.json",
        _ => "scenario.toml",
    };
    let _ = fs::write(dir.join(name), &case.text);
    let _ = fs::write(
        dir.join("case.txt"),
        format!(
            "case #{n} ({role:?})\nops: {}\nargs: {}\ndefect: {kind}: {detail}\n--- stderr ---\n{stderr}",
            case.ops.join("; "),
            args.join(" ")
        ),
    );
}

/// Counts of a whole-program fuzz run.
#[derive(Debug, Default, Clone)]
pub struct Stats {
    /// Cases.
    pub cases: u64,
    /// Exit 0 with sound outputs.
    pub ran: u64,
    /// Exit 1/2 with a message and nothing left.
    pub refused: u64,
    /// Exit 3 with the divergence recorded.
    pub diverged: u64,
    /// Defects by kind: count and the first few case numbers with detail.
    pub defects: BTreeMap<String, (u64, Vec<String>)>,
    /// Per seed: cases, ran.
    pub per_seed: BTreeMap<String, (u64, u64)>,
    /// Total and maximum wall time of a case.
    pub wall: (Duration, Duration),
}

impl Stats {
    /// Total defects.
    pub fn defect_count(&self) -> u64 {
        self.defects.values().map(|(n, _)| n).sum()
    }

    /// The report.
    pub fn report(&self) -> String {
        let mut s = format!(
            "cases {}\nran (exit 0) {}\nrefused (exit 1/2) {}\ndiverged (exit 3) {}\ndefects {}\nwall time per case: mean {:.1?}, max {:.1?}\n",
            self.cases,
            self.ran,
            self.refused,
            self.diverged,
            self.defect_count(),
            self.wall.0 / (self.cases.max(1) as u32),
            self.wall.1
        );
        for (k, (n, ex)) in &self.defects {
            s.push_str(&format!("  defect {k}: {n}\n"));
            for e in ex {
                s.push_str(&format!("    {e}\n"));
            }
        }
        for (k, (n, r)) in &self.per_seed {
            s.push_str(&format!("  seed {k}: {n} cases, {r} ran\n"));
        }
        s
    }
}

/// Runs cases `0..cases` on `s.workers` threads.
pub fn run(m: &Mutator, roles: &[Role], cases: u64, s: &Settings) -> Stats {
    let next = AtomicU64::new(0);
    let stats = Mutex::new(Stats::default());
    let progress = cases / 20;
    std::thread::scope(|scope| {
        for w in 0..s.workers {
            let (next, stats) = (&next, &stats);
            scope.spawn(move || loop {
                let n = next.fetch_add(1, Ordering::Relaxed);
                if n >= cases {
                    break;
                }
                let dir = s.work.join(format!("w{w}-{n}"));
                let (v, wall) = judge(m, roles, n, s, &dir);
                let _ = fs::remove_dir_all(&dir);
                let case = m.case(n);
                let seed = m.seeds()[case.seed].name.clone();
                let mut st = stats.lock().expect("stats");
                st.cases += 1;
                st.wall.0 += wall;
                st.wall.1 = st.wall.1.max(wall);
                let e = st.per_seed.entry(seed.clone()).or_insert((0, 0));
                e.0 += 1;
                match v {
                    Verdict::Ran => {
                        e.1 += 1;
                        st.ran += 1;
                    }
                    Verdict::Refused => st.refused += 1,
                    Verdict::Diverged => st.diverged += 1,
                    Verdict::Defect(k, d) => {
                        let e = st.defects.entry(k).or_insert((0, Vec::new()));
                        e.0 += 1;
                        if e.1.len() < 3 {
                            e.1.push(format!("#{n} {seed} ({}): {d}", case.ops.join("; ")));
                        }
                    }
                }
                if progress > 0 && st.cases % progress == 0 {
                    eprintln!(
                        "  … {} cases: {} ran, {} refused, {} diverged, {} defects",
                        st.cases,
                        st.ran,
                        st.refused,
                        st.diverged,
                        st.defect_count()
                    );
                }
            });
        }
    });
    stats.into_inner().expect("stats")
}
