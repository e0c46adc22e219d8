//! An output directory holds one study, and only the files that study wrote.
//!
//! Every writer of an output directory (`edgekf run`, `merge`, `reproduce`, `design`, SLAM runs,
//! Python's `Result.save`) first calls [`prepare`]: the directory must be new, empty, or hold
//! *the same study* — recognised by its `provenance.json`, whose `kind` (`study`, `shard`,
//! `slam`, `framework`) and `name` (the scenario's or framework's `name`) must both match, and
//! whose `files` must list every file in the directory (hidden files, such as the temporaries of
//! an interrupted write, and the files derived later from the study, [`DERIVED`], aside).
//! Anything else — another study, files edgekf did not write, outputs of an older edgekf that did
//! not list its files, the study directories of a `reproduce` output root — is refused, naming
//! what was found, unless the caller asks to empty the directory first (`--force`).
//!
//! After the new files are in place, [`Prepared::finish`] removes the files of the previous run
//! of the same study that this run did not write again (a figure the scenario no longer draws),
//! and the derived files, which described the old results. So a directory never mixes two runs,
//! and `edgekf report` shows only the files the provenance lists.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use crate::Provenance;

/// Files written into a study's directory *after* the study, from its files: the report page
/// (`edgekf report`) and the claims checked on it (`edgekf claims`). They are not in the
/// provenance's list; a new run of the study removes them (they describe the old results).
pub const DERIVED: [&str; 2] = ["report.html", "claims.json"];

/// What a directory holds: the `kind` of output and the study's `name`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StudyId {
    /// `study` (a filter study: `run`, `merge`, `reproduce`, `Result.save`), `shard`
    /// (`run --shard`), `slam` (a SLAM run) or `framework` (`design`).
    pub kind: &'static str,
    /// The scenario's (or framework's) `name`.
    pub name: String,
}

impl StudyId {
    /// A filter study's outputs.
    pub fn study(name: &str) -> Self {
        Self {
            kind: "study",
            name: name.into(),
        }
    }
    /// `kind` `name`.
    pub fn new(kind: &'static str, name: &str) -> Self {
        Self {
            kind,
            name: name.into(),
        }
    }
}

impl std::fmt::Display for StudyId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match self.kind {
            "study" => "study",
            "shard" => "shard of the study",
            "slam" => "SLAM study",
            "framework" => "design of the framework",
            other => other,
        };
        write!(f, "the {what} `{}`", self.name)
    }
}

/// How the caller names the output directory and the way to replace its contents, for the
/// messages: the CLI's `--out` / `--force`, or Python's `dir` / `force=True`.
#[derive(Debug, Clone, Copy)]
pub struct Hint {
    /// The argument that names the directory (`--out`).
    pub out: &'static str,
    /// The argument that replaces its contents (`--force`).
    pub force: &'static str,
}

impl Hint {
    /// The command line's `--out` and `--force`.
    pub const CLI: Hint = Hint {
        out: "--out",
        force: "--force",
    };
}

/// Why an output directory is refused.
#[derive(Debug, thiserror::Error)]
pub enum OutDirError {
    /// The directory holds the outputs of another study.
    #[error("{dir}: holds {found}; this is {want}. Outputs never mix: choose another {out}, or pass {force} to replace its contents")]
    OtherStudy {
        /// The directory.
        dir: String,
        /// What it holds.
        found: String,
        /// What was to be written.
        want: String,
        /// The argument naming the directory.
        out: &'static str,
        /// The argument that empties it.
        force: &'static str,
    },
    /// The directory holds files that no provenance lists.
    #[error("{dir}: holds {files}, which {which} not written by {want}. Outputs never mix: choose a new or empty {out}, or pass {force} to replace its contents")]
    Foreign {
        /// The directory.
        dir: String,
        /// The files (the first few).
        files: String,
        /// `was` or `were`.
        which: &'static str,
        /// What was to be written.
        want: String,
        /// The argument naming the directory.
        out: &'static str,
        /// The argument that empties it.
        force: &'static str,
    },
    /// Outputs of an older edgekf whose provenance does not list its files.
    #[error("{dir}: holds the outputs of {found}, written by an edgekf that did not list its files in provenance.json, so they cannot be told from this run's. Choose another {out}, or pass {force} to replace its contents")]
    Unlisted {
        /// The directory.
        dir: String,
        /// What it holds (as far as known).
        found: String,
        /// The argument naming the directory.
        out: &'static str,
        /// The argument that empties it.
        force: &'static str,
    },
    /// A `reproduce` output root (study subdirectories) where a single study was to be written.
    #[error("{dir}: holds the study directories {subdirs} (a `reproduce` output root); a study's files would mix with them. Choose another {out}, or pass {force} to replace its contents")]
    Collection {
        /// The directory.
        dir: String,
        /// The subdirectories (the first few).
        subdirs: String,
        /// The argument naming the directory.
        out: &'static str,
        /// The argument that empties it.
        force: &'static str,
    },
    /// Emptying the directory would remove the current directory or the home directory.
    #[error("{dir}: {force} would empty a directory that holds {what}; choose another {out}")]
    Unsafe {
        /// The directory.
        dir: String,
        /// What it holds.
        what: &'static str,
        /// The argument naming the directory.
        out: &'static str,
        /// The argument that empties it.
        force: &'static str,
    },
    /// The path exists and is not a directory.
    #[error("{dir}: exists and is not a directory; choose another {out}")]
    NotADirectory {
        /// The path.
        dir: String,
        /// The argument naming the directory.
        out: &'static str,
    },
    /// The directory cannot be read or emptied.
    #[error("{dir}: cannot {action}: {source}")]
    Io {
        /// The directory.
        dir: String,
        /// `list`, `empty`, …
        action: &'static str,
        /// The system's error.
        #[source]
        source: io::Error,
    },
}

impl OutDirError {
    /// The system's error kind, for `Io` (so the Python package can raise `OSError`).
    pub fn io_kind(&self) -> Option<io::ErrorKind> {
        match self {
            OutDirError::Io { source, .. } => Some(source.kind()),
            _ => None,
        }
    }
}

/// A directory checked by [`prepare`]: where the files go, and what the previous run of the
/// same study left there.
#[derive(Debug)]
#[must_use = "call finish() after the new files are in place"]
pub struct Prepared {
    dir: PathBuf,
    old: Vec<String>,
    /// `force` on a directory that held anything: at [`Prepared::finish`] everything in it but
    /// the new files goes (not before, so an interrupted run leaves the old study whole).
    forced: bool,
}

impl Prepared {
    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// After the new files are in place (`written`: their names): removes the previous run's
    /// files that were not written again, and the derived files ([`DERIVED`]); with `force`,
    /// everything else in the directory (but other processes' staging directories).
    ///
    /// # Errors
    /// A file that cannot be removed.
    pub fn finish(self, written: &[String]) -> Result<(), OutDirError> {
        if self.forced {
            return remove_all_but(&self.dir, written);
        }
        let stale = self
            .old
            .iter()
            .map(String::as_str)
            .chain(DERIVED)
            .filter(|f| !written.iter().any(|w| w == f));
        for f in stale {
            let p = self.dir.join(f);
            match fs::remove_file(&p) {
                Ok(()) => {}
                Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                Err(source) => {
                    return Err(OutDirError::Io {
                        dir: p.display().to_string(),
                        action: "remove the previous run's file",
                        source,
                    })
                }
            }
        }
        Ok(())
    }
}

/// The provenance of a directory, if it has a readable one.
pub fn provenance(dir: &Path) -> Option<Provenance> {
    let text = fs::read_to_string(dir.join("provenance.json")).ok()?;
    serde_json::from_str(&text).ok()
}

/// The visible (not hidden) entries of `dir`: (name, is a directory), sorted.
fn entries(dir: &Path) -> Result<Vec<(String, bool)>, OutDirError> {
    let rd = fs::read_dir(dir).map_err(|source| OutDirError::Io {
        dir: dir.display().to_string(),
        action: "list",
        source,
    })?;
    let mut v: Vec<(String, bool)> = rd
        .filter_map(|d| d.ok())
        .filter_map(|d| {
            let name = d.file_name().into_string().ok()?;
            let is_dir = d.file_type().ok()?.is_dir();
            (!name.starts_with('.')).then_some((name, is_dir))
        })
        .collect();
    v.sort();
    Ok(v)
}

/// `a, b, c and 4 more`.
fn few(names: &[String]) -> String {
    const SHOW: usize = 4;
    let shown: Vec<String> = names.iter().take(SHOW).map(|n| format!("`{n}`")).collect();
    if names.len() > SHOW {
        format!("{} and {} more", shown.join(", "), names.len() - SHOW)
    } else {
        shown.join(", ")
    }
}

/// What a provenance says a directory holds.
fn found(p: &Provenance) -> String {
    if p.kind.is_empty() || p.name.is_empty() {
        let cmd = p
            .command
            .iter()
            .skip(1)
            .take(3)
            .cloned()
            .collect::<Vec<_>>();
        format!("outputs of `edgekf {}`", cmd.join(" "))
    } else {
        StudyId {
            kind: match p.kind.as_str() {
                "study" => "study",
                "shard" => "shard",
                "slam" => "slam",
                "framework" => "framework",
                _ => "output",
            },
            name: p.name.clone(),
        }
        .to_string()
    }
}

/// Checks that `dir` may receive the outputs of `study` (see the module docs); with `force`,
/// its contents are replaced when the new files are in place ([`Prepared::finish`]; refused
/// for a directory that holds the current or home directory).
///
/// # Errors
/// [`OutDirError`], naming what the directory holds.
pub fn prepare(
    dir: &Path,
    study: &StudyId,
    force: bool,
    hint: Hint,
) -> Result<Prepared, OutDirError> {
    let prepared = Prepared {
        dir: dir.to_path_buf(),
        old: Vec::new(),
        forced: false,
    };
    let shown = dir.display().to_string();
    match fs::metadata(dir) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(prepared),
        Err(source) => {
            return Err(OutDirError::Io {
                dir: shown,
                action: "read",
                source,
            })
        }
        Ok(m) if !m.is_dir() => {
            return Err(OutDirError::NotADirectory {
                dir: shown,
                out: hint.out,
            })
        }
        Ok(_) => {}
    }
    let list = entries(dir)?;
    if list.is_empty() {
        return Ok(prepared);
    }
    if force {
        check_emptiable(dir, hint)?;
        return Ok(Prepared {
            forced: true,
            ..prepared
        });
    }
    let want = study.to_string();
    match provenance(dir) {
        Some(p) if p.files.is_empty() => Err(OutDirError::Unlisted {
            dir: shown,
            found: found(&p),
            out: hint.out,
            force: hint.force,
        }),
        Some(p) if p.kind != study.kind || p.name != study.name => Err(OutDirError::OtherStudy {
            dir: shown,
            found: found(&p),
            want,
            out: hint.out,
            force: hint.force,
        }),
        Some(p) => {
            let extra: Vec<String> = list
                .iter()
                .filter(|(n, _)| !p.files.contains(n) && !DERIVED.contains(&n.as_str()))
                .map(entry_shown)
                .collect();
            if !extra.is_empty() {
                let want = format!("{want} (its provenance.json does not list them)");
                return Err(foreign(shown, &extra, want, hint));
            }
            Ok(Prepared {
                dir: dir.to_path_buf(),
                old: p.files,
                forced: false,
            })
        }
        None => Err(without_provenance(dir, &list, &want, hint)),
    }
}

/// Why a directory that holds files but no provenance is refused: the study directories of a
/// `reproduce` root, or files edgekf did not write.
fn without_provenance(dir: &Path, list: &[(String, bool)], want: &str, hint: Hint) -> OutDirError {
    let shown = dir.display().to_string();
    let studies: Vec<String> = list
        .iter()
        .filter(|(n, d)| *d && dir.join(n).join("provenance.json").is_file())
        .map(|(n, _)| format!("{n}/"))
        .collect();
    if !studies.is_empty() {
        return OutDirError::Collection {
            dir: shown,
            subdirs: few(&studies),
            out: hint.out,
            force: hint.force,
        };
    }
    let names: Vec<String> = list.iter().map(entry_shown).collect();
    let want = format!("edgekf (there is no provenance.json); this is {want}");
    foreign(shown, &names, want, hint)
}

/// A directory entry as the messages show it: a directory with a trailing `/`.
fn entry_shown((name, is_dir): &(String, bool)) -> String {
    if *is_dir {
        format!("{name}/")
    } else {
        name.clone()
    }
}

/// Files in `dir` that `want` did not write.
fn foreign(dir: String, names: &[String], want: String, hint: Hint) -> OutDirError {
    OutDirError::Foreign {
        dir,
        which: if names.len() == 1 { "was" } else { "were" },
        files: few(names),
        want,
        out: hint.out,
        force: hint.force,
    }
}

/// For a command that writes files derived from a study beside it (`edgekf claims --out`, its
/// `claims.json`): whether `dir` holds the study `study`. `Ok(false)` when `dir` does not exist
/// or holds nothing visible; `Ok(true)` when its provenance names that study; otherwise the
/// reason it is refused, naming what it holds (no `--force` advice: such a command never
/// empties a directory).
///
/// # Errors
/// The message, when `dir` is not a directory, holds another study, or holds files without a
/// readable `provenance.json`.
pub fn holds(dir: &Path, study: &StudyId) -> Result<bool, String> {
    let shown = dir.display();
    if !dir.exists() {
        return Ok(false);
    }
    if !dir.is_dir() {
        return Err(format!("{shown}: exists and is not a directory"));
    }
    match provenance(dir) {
        Some(p) if p.kind == study.kind && p.name == study.name => Ok(true),
        Some(p) => Err(format!("{shown}: holds {}; this is for {study}", found(&p))),
        None => {
            let list = entries(dir).map_err(|e| e.to_string())?;
            if list.is_empty() {
                return Ok(false);
            }
            let names: Vec<String> = list.into_iter().map(|(n, _)| n).collect();
            Err(format!(
                "{shown}: holds {} and no readable provenance.json, so not {study}",
                few(&names)
            ))
        }
    }
}

/// What a study's directory holds (`the study `name``, …), from its provenance; `None` when
/// `dir` has no readable provenance.
pub fn held(dir: &Path) -> Option<String> {
    provenance(dir).map(|p| found(&p))
}

/// Checks the root of a `reproduce` output (a directory of study directories): it must not
/// itself be a study's directory. With `force`, a study's directory is emptied.
///
/// # Errors
/// [`OutDirError::OtherStudy`] naming the study found.
pub fn prepare_root(dir: &Path, force: bool, hint: Hint) -> Result<(), OutDirError> {
    let Some(p) = provenance(dir) else {
        if dir.exists() && !dir.is_dir() {
            return Err(OutDirError::NotADirectory {
                dir: dir.display().to_string(),
                out: hint.out,
            });
        }
        return Ok(());
    };
    if force {
        return empty(dir, hint);
    }
    Err(OutDirError::OtherStudy {
        dir: dir.display().to_string(),
        found: found(&p),
        want: "a `reproduce` output root (one directory per simulation)".into(),
        out: hint.out,
        force: hint.force,
    })
}

/// Removes everything in `dir` (not `dir` itself); refused when `dir` holds the current
/// directory or is the home directory.
fn empty(dir: &Path, hint: Hint) -> Result<(), OutDirError> {
    check_emptiable(dir, hint)?;
    remove_all_but(dir, &[])
}

/// Refuses to empty `dir` when it holds the current directory or is the home directory.
fn check_emptiable(dir: &Path, hint: Hint) -> Result<(), OutDirError> {
    let shown = dir.display().to_string();
    let canon = fs::canonicalize(dir).map_err(|source| OutDirError::Io {
        dir: shown.clone(),
        action: "resolve",
        source,
    })?;
    let unsafe_what = if std::env::current_dir()
        .ok()
        .and_then(|c| fs::canonicalize(c).ok())
        .is_some_and(|c| c.starts_with(&canon))
    {
        Some("the current directory")
    } else if std::env::var_os("HOME")
        .and_then(|h| fs::canonicalize(h).ok())
        .is_some_and(|h| h == canon)
    {
        Some("the home directory")
    } else {
        None
    };
    if let Some(what) = unsafe_what {
        return Err(OutDirError::Unsafe {
            dir: shown,
            what,
            out: hint.out,
            force: hint.force,
        });
    }
    Ok(())
}

/// Removes everything in `dir` but the entries named in `keep` and the staging directories
/// of processes writing there (`.edgekf-staging-PID`).
fn remove_all_but(dir: &Path, keep: &[String]) -> Result<(), OutDirError> {
    let rd = fs::read_dir(dir).map_err(|source| OutDirError::Io {
        dir: dir.display().to_string(),
        action: "list",
        source,
    })?;
    for d in rd.filter_map(|d| d.ok()) {
        let name = d.file_name();
        let name = name.to_string_lossy();
        if keep.iter().any(|k| *k == name) || name.starts_with(".edgekf-staging-") {
            continue;
        }
        let p = d.path();
        let r = if d.file_type().is_ok_and(|t| t.is_dir()) {
            fs::remove_dir_all(&p)
        } else {
            fs::remove_file(&p)
        };
        r.map_err(|source| OutDirError::Io {
            dir: p.display().to_string(),
            action: "remove (emptying the output directory)",
            source,
        })?;
    }
    Ok(())
}

/// The `provenance.json` of a directory whose other files are `files` (the names staged or
/// written; `provenance.json` is added), for `study`, run by `command`.
pub fn provenance_json(command: Vec<String>, study: &StudyId, files: &[String]) -> String {
    let mut list: Vec<String> = files.to_vec();
    list.push("provenance.json".into());
    list.sort();
    list.dedup();
    Provenance {
        kind: study.kind.into(),
        name: study.name.clone(),
        files: list,
        ..Provenance::new(command)
    }
    .to_json()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("edgekf-outdir-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    fn write_study(dir: &Path, id: &StudyId, files: &[&str]) {
        let names: Vec<String> = files.iter().map(|s| s.to_string()).collect();
        for f in files {
            fs::write(dir.join(f), "x").unwrap();
        }
        fs::write(
            dir.join("provenance.json"),
            provenance_json(vec!["edgekf".into()], id, &names),
        )
        .unwrap();
    }

    #[test]
    fn new_empty_same_other_and_foreign() {
        let d = scratch("cases");
        let a = StudyId::study("eusipco");
        // New and empty directories are fine.
        assert!(prepare(&d.join("new"), &a, false, Hint::CLI).is_ok());
        assert!(prepare(&d, &a, false, Hint::CLI).is_ok());
        // The same study: fine, and finish removes what the new run did not write again, and
        // the derived files.
        write_study(&d, &a, &["metrics.csv", "old-figure.png"]);
        fs::write(d.join("report.html"), "x").unwrap();
        fs::write(d.join(".metrics.tmp.csv"), "x").unwrap(); // hidden: ignored
        let p = prepare(&d, &a, false, Hint::CLI).unwrap();
        fs::write(d.join("metrics.csv"), "y").unwrap();
        p.finish(&["metrics.csv".into(), "provenance.json".into()])
            .unwrap();
        assert!(d.join("metrics.csv").is_file());
        assert!(!d.join("old-figure.png").exists());
        assert!(!d.join("report.html").exists());
        // Another study: refused by name.
        let e = prepare(&d, &StudyId::study("thesis-fig4.8"), false, Hint::CLI).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("`eusipco`") && m.contains("`thesis-fig4.8`") && m.contains("--force"),
            "{m}"
        );
        // The same name but another kind (a shard): refused.
        assert!(prepare(&d, &StudyId::new("shard", "eusipco"), false, Hint::CLI).is_err());
        // A file no provenance lists: refused, named.
        fs::write(d.join("notes.txt"), "mine").unwrap();
        let m = prepare(&d, &a, false, Hint::CLI).unwrap_err().to_string();
        assert!(m.contains("`notes.txt`"), "{m}");
        // --force replaces it, once the new files are in place: a run that stops before
        // (the Prepared dropped unfinished) leaves the old study whole.
        let before = entries(&d).unwrap();
        drop(prepare(&d, &StudyId::study("other"), true, Hint::CLI).unwrap());
        assert_eq!(entries(&d).unwrap(), before);
        let p = prepare(&d, &StudyId::study("other"), true, Hint::CLI).unwrap();
        fs::create_dir(d.join(".edgekf-staging-1")).unwrap();
        fs::create_dir(d.join("sub")).unwrap();
        fs::write(d.join("new.csv"), "n").unwrap();
        p.finish(&["new.csv".into()]).unwrap();
        assert_eq!(
            fs::read_dir(&d).unwrap().count(),
            2,
            "{:?}",
            entries(&d).unwrap()
        );
        assert_eq!(fs::read_to_string(d.join("new.csv")).unwrap(), "n");
        fs::remove_file(d.join("new.csv")).unwrap();
        fs::remove_dir(d.join(".edgekf-staging-1")).unwrap();
        // A directory without provenance: refused.
        fs::write(d.join("a.png"), "x").unwrap();
        let m = prepare(&d, &a, false, Hint::CLI).unwrap_err().to_string();
        assert!(
            m.contains("`a.png`") && m.contains("no provenance.json"),
            "{m}"
        );
        // An old provenance without the list of files: refused.
        fs::write(
            d.join("provenance.json"),
            Provenance::new(vec!["edgekf".into(), "run".into(), "x.toml".into()]).to_json(),
        )
        .unwrap();
        let m = prepare(&d, &a, false, Hint::CLI).unwrap_err().to_string();
        assert!(m.contains("did not list its files"), "{m}");
        let _ = fs::remove_dir_all(&d);
    }

    #[test]
    fn roots_and_collections() {
        let d = scratch("roots");
        fs::create_dir_all(d.join("eusipco")).unwrap();
        write_study(
            &d.join("eusipco"),
            &StudyId::study("eusipco"),
            &["metrics.csv"],
        );
        // A reproduce root is not a study's directory.
        let m = prepare(&d, &StudyId::study("x"), false, Hint::CLI)
            .unwrap_err()
            .to_string();
        assert!(m.contains("eusipco/") && m.contains("reproduce"), "{m}");
        assert!(prepare_root(&d, false, Hint::CLI).is_ok());
        // A study's directory is not a reproduce root.
        let m = prepare_root(&d.join("eusipco"), false, Hint::CLI)
            .unwrap_err()
            .to_string();
        assert!(m.contains("`eusipco`"), "{m}");
        // --force refuses to empty the current directory.
        let here = std::env::current_dir().unwrap();
        let m = empty(&here, Hint::CLI).unwrap_err().to_string();
        assert!(m.contains("current directory"), "{m}");
        let _ = fs::remove_dir_all(&d);
    }
}
