//! What `reproduce` and `report` write: one directory per simulation (no simulation's data twice,
//! every figure once), provenance beside the data, a report page per study, and the terminal
//! summary on stdout.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::collections::BTreeMap;
use std::fs;
use std::path::Path;
use std::process::{Command, Output};

fn edgekf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs")
}

fn tmp(name: &str) -> Scratch {
    Scratch::new("edgekf-outputs", name)
}

/// Every file under `dir`, relative, with its size.
fn files(dir: &Path) -> BTreeMap<String, u64> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().display().to_string();
                out.insert(rel, e.metadata().unwrap().len());
            }
        }
    }
    out
}

#[test]
fn reproduce_all_writes_each_simulation_once_with_its_figures_and_pages() {
    let dir = tmp("all");
    let o = edgekf(&[
        "reproduce",
        "all",
        "--out",
        dir.to_str().unwrap(),
        "--runs",
        "2",
        "--steps",
        "300",
        "--report",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let all = files(&dir);
    // One data set per scenario file: the registry's simulations, each once.
    // (A companion simulation, like the dense graph of garkf-fig13, has a directory of its own.)
    let mut sims: Vec<&str> = edgekf_io::reproductions::ENTRIES
        .iter()
        .filter(|e| !e.is_slam())
        .flat_map(|e| {
            std::iter::once(e.simulation()).chain(
                e.companions
                    .iter()
                    .map(|(file, _)| file.strip_suffix(".toml").unwrap_or(file)),
            )
        })
        .collect();
    sims.sort_unstable();
    sims.dedup();
    let metrics: Vec<&String> = all.keys().filter(|k| k.ends_with("/metrics.csv")).collect();
    assert_eq!(metrics.len(), sims.len(), "{metrics:?}");
    for s in &sims {
        for f in [
            "scenario.json",
            "metrics.csv",
            "paths.csv",
            "status.csv",
            "provenance.json",
            "report.html",
        ] {
            assert!(all.contains_key(&format!("{s}/{f}")), "{s}/{f} missing");
        }
    }
    // Every figure of every reproduction exactly once, beside its simulation's data.
    for e in edgekf_io::reproductions::ENTRIES
        .iter()
        .filter(|e| !e.is_slam())
    {
        for p in e.plots {
            let n = all
                .keys()
                .filter(|k| k.ends_with(&format!("/{p}.png")))
                .count();
            assert_eq!(n, 1, "{p}.png written {n} times");
            assert!(all.contains_key(&format!("{}/{p}.png", e.simulation())));
        }
    }
    // No two data files are byte-identical copies of each other.
    let mut seen: BTreeMap<Vec<u8>, String> = BTreeMap::new();
    for k in all.keys().filter(|k| k.ends_with(".csv")) {
        let bytes = fs::read(dir.join(k)).unwrap();
        if let Some(first) = seen.insert(bytes, k.clone()) {
            // status.csv of single-estimator studies can coincide; data files must not.
            assert!(k.ends_with("status.csv"), "{k} duplicates {first}");
        }
    }
    assert!(all.contains_key("index.html"));
    assert!(all.contains_key("slam-fig3/report.html"));
    // A sweep's page says which value its steady-state table shows.
    let page = fs::read_to_string(dir.join("garkf-fig11/report.html")).unwrap();
    assert!(
        page.contains("the table is of the scenario as written, `faults.availability` = 0.4"),
        "the swept value named"
    );
    // The steady-state table per simulation on stdout, logs on stderr.
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("eusipco: 2 run(s); steady state"),
        "{stdout}"
    );
    assert!(stdout.contains("cov_trace [m²]"), "{stdout}");
    assert!(!stdout.contains("wrote "), "logs on stdout: {stdout}");
}

#[test]
fn report_of_a_run_and_refusal_of_a_directory_without_a_study() {
    let dir = tmp("run");
    let sc = dir.join("s.toml");
    fs::write(
        &sc,
        "name = \"tiny\"\nestimators = [\"mle\", \"rkf\"]\n[framework]\npreset = \"hexagon\"\n\
         [sim]\nsteps = 200\nruns = 2\nevery = 20\n[[plots]]\nfile = \"err\"\nkind = \"metric\"\n\
         metric = \"est_error\"\nlog_y = true\nlog_x = true\n",
    )
    .unwrap();
    let out = dir.join("out");
    let o = edgekf(&["run", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let prov: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("provenance.json")).unwrap()).unwrap();
    assert_eq!(prov["schema"], "edgekf.provenance/1");
    assert_eq!(prov["command"][1], "run");
    let o = edgekf(&["report", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("data:image/png;base64,"));
    assert!(html.contains("No claims checked for this study"));
    assert!(html.contains("<td>rkf</td>"));
    // A malformed claims.json is an error naming the file, not a silent page.
    fs::write(out.join("claims.json"), "[{\"id\": 1}]").unwrap();
    let o = edgekf(&["report", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("claims.json"));
    let o = edgekf(&["report", dir.join("nothing").to_str().unwrap()]);
    assert!(!o.status.success());
    fs::create_dir_all(dir.join("empty")).unwrap();
    let o = edgekf(&["report", dir.join("empty").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no study here"));
}
