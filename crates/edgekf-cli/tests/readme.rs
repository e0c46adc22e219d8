//! The README and the user guide say what the commands print and do: the README's terminal
//! example is the output of its command (rewritten by `EDGEKF_UPDATE_README=1 cargo test -p
//! edgekf-cli --test readme`; the guide includes it), the guide's table of reproductions names
//! every reproduction and scenario file, it names every key a framework file needs, its
//! 1,000-agent recipe runs (and the CRKF in it is refused by the default limit), and `figures/`
//! is ignored by git. Each section is found by its marker (`<!-- terminal-example … -->`, …) in
//! whichever of `README.md`, `ARCHITECTURE.md` and the guide's chapters (`docs/book/src/`) holds
//! it — exactly one must — so the documents can be restructured around them.

#[path = "scratch/mod.rs"]
mod scratch;
use scratch::Scratch;
use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The Markdown files a marker may be in: the README, ARCHITECTURE.md, and every chapter of the
/// user guide (the guide's sources, `docs/book/src/**/*.md`).
fn documents() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<PathBuf> = fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "md") {
                out.push(p);
            }
        }
    }
    let mut out = vec![root().join("README.md"), root().join("ARCHITECTURE.md")];
    let book = root().join("docs/book/src");
    let before = out.len();
    walk(&book, &mut out);
    assert!(
        out.len() > before + 10,
        "the user guide's chapters in {}",
        book.display()
    );
    out
}

/// The one document that holds `marker`: (its path, its text).
fn holding(marker: &str) -> (PathBuf, String) {
    let found: Vec<(PathBuf, String)> = documents()
        .into_iter()
        .map(|p| {
            let t = fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p, t)
        })
        .filter(|(_, t)| t.contains(marker))
        .collect();
    let names: Vec<String> = found.iter().map(|(p, _)| p.display().to_string()).collect();
    assert_eq!(
        found.len(),
        1,
        "`{marker}` must be in exactly one of the README, ARCHITECTURE.md and the guide's \
         chapters: {names:?}"
    );
    found.into_iter().next().unwrap()
}

/// The text after `marker` up to `end`, in the document that holds `marker`.
fn section(marker: &str, end: &str) -> String {
    let (path, text) = holding(marker);
    let at = text.find(marker).unwrap();
    let rest = &text[at + marker.len()..];
    let stop = rest
        .find(end)
        .unwrap_or_else(|| panic!("{}: `{end}` after `{marker}`", path.display()));
    rest[..stop].to_string()
}

/// The first fenced block after `marker` in `text`: (byte range of its body in `text`, body).
fn block_after(text: &str, marker: &str) -> (std::ops::Range<usize>, String) {
    let at = text.find(marker).unwrap_or_else(|| panic!("no `{marker}`"));
    let open = at + text[at..].find("```").expect("a fenced block");
    let body = open + text[open..].find('\n').expect("fence line") + 1;
    let close = body + text[body..].find("```").expect("closing fence");
    // The closing fence's indentation belongs to it, not to the body.
    let end = text[..close].rfind('\n').map_or(close, |n| n + 1);
    (body..end, text[body..end].to_string())
}

/// Backticked words of `text`.
fn ticked(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

#[test]
fn terminal_example_is_what_its_command_prints() {
    let dir = Scratch::new("edgekf-readme", "terminal");
    let marker = "<!-- terminal-example: edgekf run scenarios/eusipco.toml --out out";
    let (path, text) = holding(marker);
    let (range, shown) = block_after(&text, marker);
    let o = Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(["run", "scenarios/eusipco.toml", "--out"])
        .arg(dir.join("out"))
        .current_dir(root())
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let printed = String::from_utf8(o.stdout).unwrap();
    if std::env::var_os("EDGEKF_UPDATE_README").is_some() && printed != shown {
        let mut new = text.clone();
        new.replace_range(range, &printed);
        fs::write(&path, new).unwrap();
        eprintln!("{}: terminal example rewritten", path.display());
        return;
    }
    assert_eq!(
        shown,
        printed,
        "the terminal example of {} is not what `edgekf run scenarios/eusipco.toml --out out` \
         prints; EDGEKF_UPDATE_README=1 cargo test -p edgekf-cli --test readme rewrites it",
        path.display()
    );
}

#[test]
fn the_table_of_reproductions_names_every_one_and_every_scenario_file() {
    let table = section("<!-- reproductions", "<!-- /reproductions -->");
    let mut names = BTreeSet::new();
    let mut files = BTreeSet::new();
    for row in table.lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = row.split('|').collect();
        names.extend(ticked(cells[1]));
        files.extend(ticked(cells[3]));
    }
    let o = Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(["reproduce", "--list"])
        .output()
        .expect("runs");
    let listed: BTreeSet<String> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| l.split('\t').next().unwrap().to_string())
        .collect();
    assert_eq!(
        names, listed,
        "the guide's table vs `edgekf reproduce --list`"
    );
    // Every scenario file a reproduction simulates, its companions (such as
    // garkf-fig13-dense.toml) included.
    let mut want = BTreeSet::new();
    for e in edgekf_io::reproductions::ENTRIES {
        want.insert(e.file.to_string());
        want.extend(e.companions.iter().map(|(f, _)| f.to_string()));
    }
    assert_eq!(
        files, want,
        "the guide's table vs the shipped scenario files"
    );
}

#[test]
fn the_guide_names_every_key_a_framework_file_needs() {
    let keys = section("<!-- framework-keys -->", "<!-- /framework-keys -->");
    let (needed, optional) = keys.split_once("optional").expect("needed, then optional");
    let needed: BTreeSet<String> = ticked(needed)
        .into_iter()
        .filter(|k| !k.starts_with('"'))
        .collect();
    let optional: BTreeSet<String> = ticked(optional).into_iter().collect();
    // The keys the parser needs: those whose removal from a complete file makes it fail.
    let full = serde_json::json!({
        "schema": "edgekf.framework/1", "name": "square", "dim": 2,
        "config": [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        "edges": [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]],
        "weights": [1.0, -1.0, 1.0, 1.0, -1.0, 1.0], "leaders": [0, 1, 2]
    });
    let obj = full.as_object().unwrap();
    assert!(edgekf_io::framework::FrameworkFile::parse(&full.to_string()).is_ok());
    let mut required = BTreeSet::new();
    for k in obj.keys() {
        let mut less = obj.clone();
        less.remove(k);
        let t = serde_json::Value::Object(less).to_string();
        if edgekf_io::framework::FrameworkFile::parse(&t).is_err() {
            required.insert(k.clone());
        }
    }
    assert_eq!(
        needed, required,
        "the guide: the keys a framework file needs"
    );
    let all: BTreeSet<String> = obj.keys().cloned().collect();
    let rest: BTreeSet<String> = all.difference(&required).cloned().collect();
    assert_eq!(optional, rest, "the guide: the optional keys");
}

/// The Speed chapter's 1,000-agent run, from the command line, as the guide writes it.
#[test]
fn the_scale_recipe_runs_and_the_crkf_in_it_is_refused() {
    let dir = Scratch::new("edgekf-readme", "scale");
    let marker = "<!-- scale-recipe -->";
    let (_, text) = holding(marker);
    let (_, block) = block_after(&text, marker);
    // The block sits in a list item: two spaces of indentation.
    let script: String = block
        .lines()
        .map(|l| l.strip_prefix("  ").unwrap_or(l))
        .collect::<Vec<_>>()
        .join("\n");
    let bin = Path::new(env!("CARGO_BIN_EXE_edgekf")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let o = Command::new("bash")
        .args(["-c", &script])
        .env("PATH", path)
        .current_dir(&dir)
        .output()
        .expect("bash runs");
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(dir.join("scale1000/framework.json").is_file(), "{err}");
    let metrics = fs::read_to_string(dir.join("scale1000-run/metrics.csv")).unwrap_or_default();
    assert!(
        metrics.contains("\nrkf,2000,") && metrics.contains("\njrkf,2000,"),
        "{err}"
    );
    assert!(
        err.contains("scale-1000: this study would take about")
            && err.contains("the limit is 1 h (`--max-hours`"),
        "{err}"
    );
    assert!(!dir.join("scale1000-crkf").exists());
    assert_eq!(
        o.status.code(),
        Some(1),
        "the last command is refused: {err}"
    );
}

#[test]
fn figures_and_out_are_ignored_by_git() {
    let ignore = fs::read_to_string(root().join(".gitignore")).unwrap();
    for want in ["/figures", "/out"] {
        assert!(ignore.lines().any(|l| l.trim() == want), "{want}");
    }
}
