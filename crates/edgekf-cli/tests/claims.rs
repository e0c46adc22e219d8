//! `edgekf claims`: the JSON array has exactly the keys the report page reads, `--out` writes it
//! for the whole run and into each simulation directory `reproduce` wrote (never into another
//! study's files), and a bad name fails cleanly. The claims of
//! `slam-fig3` are deterministic and take a fraction of a second.

use std::fs;
use std::process::Command;

fn edgekf(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs")
}

#[test]
fn json_has_exactly_the_keys_and_out_writes_each_simulation() {
    let dir = std::env::temp_dir().join(format!("edgekf-cli-claims-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    let o = edgekf(&["reproduce", "slam-fig3", "--out", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = edgekf(&[
        "claims",
        "slam-fig3",
        "--json",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let printed: serde_json::Value = serde_json::from_slice(&o.stdout).expect("a JSON array");
    let rows = printed.as_array().expect("an array");
    assert!(rows.len() >= 10, "{} claims of slam-fig3", rows.len());
    let keys = [
        "claim",
        "id",
        "paper",
        "paper_value",
        "se",
        "value",
        "verdict",
        "where",
    ];
    for r in rows {
        let obj = r.as_object().expect("objects");
        let mut k: Vec<&str> = obj.keys().map(String::as_str).collect();
        k.sort_unstable();
        assert_eq!(k, keys, "{r}");
        let verdict = obj["verdict"].as_str().unwrap();
        assert!(
            ["agrees", "differs", "not checkable"].contains(&verdict),
            "{verdict}"
        );
        assert!(obj["value"].is_number() || obj["value"].is_null());
        assert!(obj["se"].is_number() || obj["se"].is_null());
        for s in ["id", "paper", "where", "claim", "paper_value"] {
            assert!(obj[s].is_string(), "{s}");
        }
    }
    // The SLAM observer's numbers are exact: standard error 0.
    let omega = rows
        .iter()
        .find(|r| r["id"] == "guo-6-omega-positive")
        .expect("the Ω claim");
    assert_eq!(omega["se"], 0.0);
    assert_eq!(omega["verdict"], "agrees");
    for f in ["claims.json", "slam-fig3/claims.json"] {
        let written: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(dir.join(f)).unwrap()).unwrap();
        assert_eq!(written, printed, "{f}");
    }
    let md = fs::read_to_string(dir.join("claims.md")).unwrap();
    assert!(md.contains("`guo-6-omega-positive`"));
    let _ = fs::remove_dir_all(&dir);
}

/// `claims --out` into a study's own directory is refused before anything runs, and nothing is
/// written there; into a new directory it writes the whole run's files and no simulation
/// directory (one holding only `claims.json` would be refused by a later `reproduce`).
#[test]
fn out_never_mixes_with_a_study() {
    let base = std::env::temp_dir().join(format!("edgekf-cli-claims-mix-{}", std::process::id()));
    let _ = fs::remove_dir_all(&base);
    let study = base.join("study");
    let o = edgekf(&["reproduce", "slam-fig3", "--out", base.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    fs::rename(base.join("slam-fig3"), &study).unwrap();
    let before: Vec<_> = fs::read_dir(&study)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    let o = edgekf(&["claims", "slam-fig3", "--out", study.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("holds the SLAM study `slam-fig3`, not the output of `edgekf reproduce`"),
        "{err}"
    );
    assert!(
        !err.contains("checking"),
        "refused before the simulations: {err}"
    );
    let after: Vec<_> = fs::read_dir(&study)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(before, after);

    let fresh = base.join("fresh");
    let o = edgekf(&["claims", "slam-fig3", "--out", fresh.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("has no directory of slam-fig3"));
    let mut names: Vec<_> = fs::read_dir(&fresh)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["claims.json", "claims.md"]);
    let o = edgekf(&["reproduce", "slam-fig3", "--out", fresh.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // A simulation's directory that holds another study, or files without a provenance, is
    // refused naming it; an empty one is no directory; a file is no root.
    let root = base.join("root");
    fs::create_dir_all(&root).unwrap();
    let refused = |what: &str| {
        let o = edgekf(&["claims", "slam-fig3", "--out", root.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(!o.status.success() && err.contains(what), "{what}: {err}");
        assert!(!root.join("claims.json").exists(), "{what}");
    };
    fs::rename(&study, root.join("slam-fig3")).unwrap();
    fs::write(
        root.join("slam-fig3/provenance.json"),
        fs::read_to_string(root.join("slam-fig3/provenance.json"))
            .unwrap()
            .replace("\"slam-fig3\"", "\"elsewhere\""),
    )
    .unwrap();
    refused("holds the SLAM study `elsewhere`; this is for the SLAM study `slam-fig3`");
    fs::remove_dir_all(root.join("slam-fig3")).unwrap();
    fs::create_dir(root.join("slam-fig3")).unwrap();
    fs::write(root.join("slam-fig3/notes.txt"), "mine").unwrap();
    refused("holds `notes.txt` and no readable provenance.json");
    fs::remove_file(root.join("slam-fig3/notes.txt")).unwrap();
    let o = edgekf(&["claims", "slam-fig3", "--out", root.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!root.join("slam-fig3/claims.json").exists());
    let file = base.join("a-file");
    fs::write(&file, "x").unwrap();
    let o = edgekf(&["claims", "slam-fig3", "--out", file.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("exists and is not a directory"));
    let _ = fs::remove_dir_all(&base);
}

#[test]
fn table_by_default_and_unknown_names_fail() {
    let o = edgekf(&["claims", "slam-disturbed"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.starts_with("| id | paper, where | claim | paper's value | ours ± SE | verdict |"));
    assert!(text.contains("`guo-5-l2-stable`"), "{text}");
    let o = edgekf(&["claims", "no-such-figure"]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("unknown reproduction `no-such-figure`"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.stdout.is_empty());
}
