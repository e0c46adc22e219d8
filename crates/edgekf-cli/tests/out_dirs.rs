//! Outputs never mix: an output directory that holds another study's files (or files edgekf did
//! not write) is refused by name, or emptied with `--force`; a re-run of the same study (the
//! same kind of output and scenario `name`, recorded in `provenance.json`) replaces its files and
//! removes the ones it did not write again; `provenance.json` lists the files written, and
//! `edgekf report` shows only those. For every command that writes a directory: `run` (and
//! `run --shard`), `merge`, `reproduce`, `design`, SLAM runs.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn edgekf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new("edgekf-outdirs", name)
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A hexagon study named `name` with one figure `figure`.
fn scenario(dir: &Path, file: &str, name: &str, figure: &str) -> PathBuf {
    let p = dir.join(file);
    fs::write(
        &p,
        format!(
            "name = \"{name}\"\nestimators = [\"mle\", \"rkf\"]\n[framework]\npreset = \"hexagon\"\n\
             [sim]\nsteps = 100\nruns = 2\nevery = 20\n\
             [[plots]]\nfile = \"{figure}\"\nkind = \"metric\"\nmetric = \"est_error\"\n"
        ),
    )
    .unwrap();
    p
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .filter_map(|d| d.ok()?.file_name().into_string().ok())
        .collect();
    v.sort();
    v
}

fn provenance(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(dir.join("provenance.json")).unwrap()).unwrap()
}

fn run(sc: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    edgekf(&args)
}

/// The case: a new study written where the EUSIPCO results were left their PNGs beside
/// the new files, and the report showed them as the new study's.
#[test]
fn run_refuses_another_study_and_reruns_its_own() {
    let dir = tmp("run");
    let out = dir.join("out");
    let a = scenario(&dir, "a.toml", "study-a", "fig-a");
    let o = run(&a, &out, &[]);
    assert!(o.status.success(), "{}", err(&o));
    // The provenance names the study and lists every file written, itself included.
    let p = provenance(&out);
    assert_eq!(p["kind"], "study");
    assert_eq!(p["name"], "study-a");
    let listed: Vec<String> = p["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    assert_eq!(listed, names(&out));
    assert!(
        listed.contains(&"fig-a.png".to_string())
            && listed.contains(&"provenance.json".to_string())
    );
    let before = fs::read(out.join("metrics.csv")).unwrap();

    // Another study: refused by name, nothing touched.
    let b = scenario(&dir, "b.toml", "study-b", "fig-b");
    let o = run(&b, &out, &[]);
    let e = err(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("`study-a`") && e.contains("`study-b`") && e.contains("--force"),
        "{e}"
    );
    assert_eq!(names(&out), listed);
    assert_eq!(fs::read(out.join("metrics.csv")).unwrap(), before);

    // The same study again, now drawing another figure: accepted; the old figure is removed
    // (and the report page, which described the old results).
    let o = edgekf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(out.join("report.html").is_file());
    let a2 = scenario(&dir, "a2.toml", "study-a", "fig-a2");
    let o = run(&a2, &out, &["--seed", "5"]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(out.join("fig-a2.png").is_file());
    assert!(!out.join("fig-a.png").exists(), "{:?}", names(&out));
    assert!(!out.join("report.html").exists());
    assert_ne!(fs::read(out.join("metrics.csv")).unwrap(), before);
    let p = provenance(&out);
    assert_eq!(p["files"].as_array().unwrap().len(), names(&out).len());

    // A file edgekf did not write: refused, named.
    fs::write(out.join("notes.txt"), "mine").unwrap();
    let o = run(&a2, &out, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(err(&o).contains("`notes.txt`"), "{}", err(&o));

    // --force empties it, then writes the other study.
    let o = run(&b, &out, &["--force"]);
    assert!(o.status.success(), "{}", err(&o));
    assert!(!out.join("notes.txt").exists() && !out.join("fig-a2.png").exists());
    assert_eq!(provenance(&out)["name"], "study-b");

    // A directory with files but no provenance (not edgekf's): refused.
    let other = dir.join("photos");
    fs::create_dir_all(&other).unwrap();
    fs::write(other.join("cat.png"), "x").unwrap();
    let o = run(&a, &other, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(err(&o).contains("`cat.png`"), "{}", err(&o));
    assert_eq!(names(&other), vec!["cat.png".to_string()]);
}

/// `report` shows only the files the provenance lists: a PNG left by another study (as an older
/// edgekf would have left it) is neither drawn nor listed.
#[test]
fn report_shows_only_the_studys_own_files() {
    let dir = tmp("report");
    let out = dir.join("out");
    let a = scenario(&dir, "a.toml", "study-a", "fig-a");
    assert!(run(&a, &out, &[]).status.success());
    fs::copy(out.join("fig-a.png"), out.join("eusipco-fig4a.png")).unwrap();
    let o = edgekf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", err(&o));
    let page = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("fig-a.png"));
    assert!(
        !page.contains("eusipco-fig4a"),
        "a stray figure is not the study's"
    );
    // A directory of an older edgekf (no list of files): every file is shown, with a note.
    let mut p = provenance(&out);
    p.as_object_mut().unwrap().remove("files");
    fs::write(out.join("provenance.json"), p.to_string()).unwrap();
    let o = edgekf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", err(&o));
    let page = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("eusipco-fig4a") && page.contains("does not list the study's files"));
}

#[test]
fn shards_merge_and_their_directories_do_not_mix() {
    let dir = tmp("shards");
    let a = scenario(&dir, "a.toml", "study-a", "fig-a");
    let (s1, s2, whole) = (dir.join("s1"), dir.join("s2"), dir.join("whole"));
    assert!(run(&a, &s1, &["--shard", "1/2"]).status.success());
    assert!(run(&a, &s2, &["--shard", "2/2"]).status.success());
    assert_eq!(provenance(&s1)["kind"], "shard");
    // The same shard again: fine. The whole study into a shard's directory: refused.
    assert!(run(&a, &s1, &["--shard", "1/2"]).status.success());
    let o = run(&a, &s1, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(err(&o).contains("shard"), "{}", err(&o));
    // Merging into a shard's directory: refused; into a new one, then again: fine.
    let (p1, p2) = (s1.to_str().unwrap(), s2.to_str().unwrap());
    let o = edgekf(&["merge", p1, p2, "--out", p1]);
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    for _ in 0..2 {
        let o = edgekf(&["merge", p1, p2, "--out", whole.to_str().unwrap()]);
        assert!(o.status.success(), "{}", err(&o));
    }
    assert_eq!(provenance(&whole)["kind"], "study");
}

#[test]
fn reproduce_checks_every_directory_before_running() {
    let dir = tmp("reproduce");
    let root = dir.join("figures");
    let rep = |extra: &[&str]| {
        let mut args = vec![
            "reproduce",
            "thesis-fig3.3",
            "--out",
            root.to_str().unwrap(),
            "--runs",
            "2",
            "--steps",
            "100",
        ];
        args.extend_from_slice(extra);
        edgekf(&args)
    };
    assert!(rep(&[]).status.success());
    // Again: the same studies, fine.
    let o = rep(&[]);
    assert!(o.status.success(), "{}", err(&o));
    let sim = root.join("thesis-fig3.3");
    assert_eq!(provenance(&sim)["name"], "thesis-fig3.3");
    // A simulation's directory that holds another study: refused before anything runs.
    let a = scenario(&dir, "a.toml", "study-a", "fig-a");
    assert!(run(&a, &sim, &["--force"]).status.success());
    let o = rep(&[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err(&o).contains("`study-a`") && !err(&o).contains("simulated"),
        "{}",
        err(&o)
    );
    assert!(rep(&["--force"]).status.success());
    assert_eq!(provenance(&sim)["name"], "thesis-fig3.3");
    // A study's directory is not a reproduce root, and a reproduce root is not a study's.
    let o = rep(&[]);
    assert!(o.status.success());
    let o = edgekf(&[
        "reproduce",
        "thesis-fig3.3",
        "--out",
        sim.to_str().unwrap(),
        "--runs",
        "2",
        "--steps",
        "100",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    let o = run(&a, &root, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(err(&o).contains("thesis-fig3.3/"), "{}", err(&o));
}

/// A figure reproduced on its own brings the other figures of its simulation, so reproducing
/// one after another into the same root keeps both (a re-run removes the files it does not
/// write again); a SLAM study is not sized by the filter studies' flags: alone it is refused,
/// beside filter studies it is named.
#[test]
fn reproduce_keeps_a_simulations_figures_together() {
    let dir = tmp("siblings");
    let root = dir.join("figures");
    let rep = |names: &[&str], extra: &[&str]| {
        let mut args = vec!["reproduce"];
        args.extend_from_slice(names);
        args.extend_from_slice(&["--out", root.to_str().unwrap()]);
        args.extend_from_slice(extra);
        edgekf(&args)
    };
    let small = ["--runs", "2", "--steps", "100"];
    for name in ["thesis-fig3.3", "thesis-fig3.4"] {
        let o = rep(&[name], &small);
        assert!(o.status.success(), "{}", err(&o));
        let sim = root.join("thesis-fig3.3");
        assert!(sim.join("thesis-fig3.3.png").is_file(), "{:?}", names(&sim));
        assert!(sim.join("thesis-fig3.4.png").is_file(), "{:?}", names(&sim));
    }
    let o = rep(&["slam-fig3"], &["--steps", "100"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err(&o).contains("slam-fig3: --runs, --steps"),
        "{}",
        err(&o)
    );
    assert!(!root.join("slam-fig3").exists());
    let o = rep(&["slam-fig3", "thesis-fig3.3"], &small);
    assert!(o.status.success(), "{}", err(&o));
    assert!(
        err(&o).contains("note: slam-fig3 at the size of its file"),
        "{}",
        err(&o)
    );
}

#[test]
fn design_and_slam_directories_hold_one_output() {
    let dir = tmp("design");
    let out = dir.join("fw");
    let design = |generate: &str, extra: &[&str]| {
        let mut args = vec![
            "design",
            "--generate",
            generate,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        edgekf(&args)
    };
    assert!(design("hexagon", &[]).status.success());
    let p = provenance(&out);
    assert_eq!(p["kind"], "framework");
    assert_eq!(
        p["files"],
        serde_json::json!(["framework.json", "framework.png", "provenance.json"])
    );
    assert!(design("hexagon", &[]).status.success());
    let o = design("zhao7", &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(err(&o).contains("hexagon"), "{}", err(&o));
    assert!(design("zhao7", &["--force"]).status.success());
    // A study into a design's directory: refused.
    let a = scenario(&dir, "a.toml", "study-a", "fig-a");
    assert_eq!(run(&a, &out, &[]).status.code(), Some(1));

    // SLAM: the same.
    let slam = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/slam-fig3.toml");
    let text = fs::read_to_string(&slam)
        .unwrap()
        .replace("horizon = 10.0", "horizon = 0.5");
    let s = dir.join("slam.toml");
    fs::write(&s, text).unwrap();
    let so = dir.join("slam");
    assert!(run(&s, &so, &[]).status.success());
    assert_eq!(provenance(&so)["kind"], "slam");
    assert!(run(&s, &so, &[]).status.success());
    assert_eq!(run(&a, &so, &[]).status.code(), Some(1));
    let mut want = names(&so);
    want.retain(|f| f != "provenance.json");
    assert_eq!(
        want,
        [
            "errors.png",
            "paths.png",
            "robots.csv",
            "scenario.json",
            "team.csv"
        ]
    );
}
