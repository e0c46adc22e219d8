//! Ctrl-C: `edgekf run` interrupted at any moment of its life (start, loading, simulating,
//! writing) ends within 2 s with exit code 130 and one line saying what was (not) written, and
//! what it says is what is on disk: nothing (no visible file), or the whole study.
//!
//! No fixed sleeps: the single-signal test waits for the line the run prints before simulating;
//! the stress test sends its signals at random moments (fixed seed) and waits on the process.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::fs;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};

fn tmp(name: &str) -> Scratch {
    Scratch::new("edgekf-interrupt", name)
}

fn sigint(child: &Child) {
    // SAFETY: kill(2) on a child we started and have not reaped.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
}

/// Waits for `child` up to `limit`; `None` (and the child killed) past it.
fn wait_for(child: &mut Child, limit: Duration) -> Option<ExitStatus> {
    let start = Instant::now();
    let mut pause = Duration::from_micros(200);
    loop {
        if let Some(s) = child.try_wait().expect("wait") {
            return Some(s);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(pause);
        pause = (pause * 2).min(Duration::from_millis(5));
    }
}

const SCENARIO: &str = "name = \"ctrl-c\"\nestimators = [\"mle\", \"rkf\", \"jrkf\"]\n\
[framework]\npreset = \"hexagon\"\n[sim]\nsteps = 300\nruns = 4\nevery = 4\n\
[[plots]]\nfile = \"errors\"\nkind = \"metric\"\nmetric = \"est_error\"\n";

/// The visible files of `dir` (none when it does not exist).
fn visible(dir: &Path) -> Vec<String> {
    let Ok(rd) = fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<String> = rd
        .filter_map(|d| d.ok()?.file_name().into_string().ok())
        .filter(|n| !n.starts_with('.'))
        .collect();
    v.sort();
    v
}

/// Checks that the directory matches what the run said; returns which case it was.
fn check_outcome(status: ExitStatus, stderr: &str, out: &Path) -> &'static str {
    let last = stderr.lines().last().unwrap_or("");
    let files = visible(out);
    let hidden: Vec<String> = fs::read_dir(out)
        .map(|rd| {
            rd.filter_map(|d| d.ok()?.file_name().into_string().ok())
                .filter(|n| n.starts_with('.'))
                .collect()
        })
        .unwrap_or_default();
    let complete = || {
        let p: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(out.join("provenance.json")).unwrap())
                .unwrap();
        let listed: Vec<&str> = p["files"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(listed, files, "{stderr}");
        assert!(files.contains(&"metrics.csv".to_string()), "{stderr}");
    };
    match (status.code(), status.signal()) {
        (Some(0), _) => {
            complete();
            "finished"
        }
        (Some(130), _) => {
            assert!(
                last.starts_with("edgekf: interrupted (Ctrl-C): "),
                "the last line says it: {stderr:?}"
            );
            assert_eq!(
                stderr.matches("interrupted").count(),
                1,
                "one line: {stderr:?}"
            );
            assert!(hidden.is_empty(), "temporaries removed: {hidden:?}");
            if last.ends_with("nothing was written") {
                assert!(files.is_empty(), "{files:?}: {stderr}");
                "nothing"
            } else {
                assert!(last.contains("written completely"), "{stderr}");
                complete();
                "written"
            }
        }
        // Before the handler is installed (the first instants of the process): the default
        // action, with nothing printed and nothing written.
        (None, Some(libc::SIGINT)) => {
            assert!(stderr.is_empty() && files.is_empty(), "{stderr}");
            "default"
        }
        other => panic!("unexpected end {other:?}: {stderr}"),
    }
}

/// [`SCENARIO`] long enough to be announced ("estimated …", printed before the simulation
/// starts) and to be still running when a signal lands.
fn long_scenario() -> String {
    SCENARIO
        .replace("steps = 300", "steps = 50000000")
        .replace("every = 4", "every = 1000000")
}

/// `edgekf run SC --out OUT EXTRA` sent `signal` once it has announced its estimate: its exit
/// status and what it printed after that line. Asserts that it ends within 2 s.
fn run_signalled(
    sc: &Path,
    out: &Path,
    extra: &[&str],
    signal: libc::c_int,
) -> (ExitStatus, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starts");
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.contains("estimated"), "{line}");
    let sent = Instant::now();
    // SAFETY: kill(2) on a child we started and have not reaped.
    unsafe {
        libc::kill(child.id() as libc::pid_t, signal);
    }
    let status = wait_for(&mut child, Duration::from_secs(2)).expect("ends within 2 s");
    assert!(sent.elapsed() < Duration::from_secs(2));
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    (status, rest)
}

/// The visible files of `dir` with their bytes.
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    visible(dir)
        .into_iter()
        .map(|f| (f.clone(), fs::read(dir.join(&f)).unwrap()))
        .collect()
}

/// One Ctrl-C (or SIGTERM) while the study simulates: exit 130 (143) and one line, nothing
/// written.
#[test]
fn ctrl_c_during_a_run_says_nothing_was_written() {
    for (signal, code, how) in [
        (libc::SIGINT, 130, "interrupted (Ctrl-C)"),
        (libc::SIGTERM, 143, "terminated (SIGTERM)"),
    ] {
        let dir = tmp(&format!("one-{signal}"));
        let sc = dir.join("s.toml");
        fs::write(&sc, long_scenario()).unwrap();
        let out = dir.join("out");
        let (status, rest) = run_signalled(&sc, &out, &[], signal);
        assert_eq!(status.code(), Some(code), "{rest}");
        assert_eq!(
            rest.trim_end(),
            format!("edgekf: {how}: nothing was written")
        );
        assert!(visible(&out).is_empty() && !out.exists());
    }
}

/// `--force` over another study, then Ctrl-C while simulating: the old study is still there,
/// whole, as the line "nothing was written" implies (the old files go only once the new ones
/// are in place).
#[test]
fn ctrl_c_after_force_leaves_the_old_study() {
    let dir = tmp("force");
    let (old, sc) = (dir.join("old.toml"), dir.join("s.toml"));
    fs::write(&old, SCENARIO.replace("\"ctrl-c\"", "\"old\"")).unwrap();
    fs::write(&sc, long_scenario()).unwrap();
    let out = dir.join("out");
    let first = Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(["run", old.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(first.status.success());
    let before = contents(&out);
    let (status, rest) = run_signalled(&sc, &out, &["--force"], libc::SIGINT);
    assert_eq!(status.code(), Some(130), "{rest}");
    assert!(rest.ends_with("nothing was written\n"), "{rest}");
    assert!(
        contents(&out) == before,
        "the old study changed: {:?}",
        visible(&out)
    );
}

/// A few hundred signals at random moments of short runs (start, loading, simulating, writing
/// the tables and figures): every run ends within 2 s, and says what is on disk.
#[test]
fn ctrl_c_at_random_moments_always_ends_promptly_and_truthfully() {
    let dir = tmp("stress");
    let sc = dir.join("s.toml");
    fs::write(&sc, SCENARIO).unwrap();
    let exe = env!("CARGO_BIN_EXE_edgekf");
    let start = |out: &Path| {
        Command::new(exe)
            .args([
                "run",
                sc.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--threads",
                "1",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starts")
    };
    // How long one run lives, uninterrupted (the signals fall in 0..1.2× of it).
    let t = Instant::now();
    let mut c = start(&dir.join("reference"));
    let s = wait_for(&mut c, Duration::from_secs(60)).expect("the reference run ends");
    assert!(s.success());
    let life = t.elapsed();
    let cases: usize = std::env::var("EDGEKF_INTERRUPT_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2026);
    let mut seen = std::collections::BTreeMap::<&str, usize>::new();
    // Two at a time (two cores).
    for pair in 0..cases.div_ceil(2) {
        let mut running = Vec::new();
        for k in 0..2 {
            let out = dir.join(format!("o{}", 2 * pair + k));
            let delay = life.mul_f64(rng.random_range(0.0..1.2));
            running.push((start(&out), out, delay, Instant::now()));
        }
        for (child, _, delay, born) in &mut running {
            let now = born.elapsed();
            if *delay > now {
                std::thread::sleep(*delay - now);
            }
            sigint(child);
            *born = Instant::now();
        }
        for (mut child, out, delay, sent) in running {
            let status = wait_for(&mut child, Duration::from_secs(2));
            let mut stderr = String::new();
            let _ = child.stderr.take().unwrap().read_to_string(&mut stderr);
            let status = status.unwrap_or_else(|| {
                panic!("did not end within 2 s of a SIGINT sent {delay:?} into its life: {stderr}")
            });
            assert!(sent.elapsed() < Duration::from_secs(3));
            *seen
                .entry(check_outcome(status, &stderr, &out))
                .or_default() += 1;
            let _ = fs::remove_dir_all(&out);
        }
    }
    eprintln!("{cases} signals over a life of {life:?}: {seen:?}");
    // The signals landed before, during and after the writing.
    assert!(seen.get("nothing").copied().unwrap_or(0) > 0, "{seen:?}");
}
