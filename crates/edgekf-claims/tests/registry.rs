//! The registry is well formed, and the verdicts written in the README, ARCHITECTURE.md, the
//! user guide (`docs/book/src/`) and `docs/claims.md` are the registry's: the documents'
//! citations must match `docs/claims.md` (instant), the claims settled at reduced size are
//! re-measured here (a few seconds), and the full check runs in the ignored test (`cargo test
//! --release -p edgekf-claims -- --ignored`, the same work as `edgekf claims`).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

use edgekf_claims::readme::{citations, is_claim_id};
use edgekf_claims::{evaluate, registry, Claim, Options, Paper, Silent, Size, Verdict};

const README: &str = include_str!("../../../README.md");
const DOCS: &str = include_str!("../../../docs/claims.md");
/// The heading of the guide's chapter that lists the claims we could not confirm.
const SECTION: &str = "What the papers claim that we could not confirm";

/// The prose that cites claims: the README, ARCHITECTURE.md and every chapter of the user
/// guide (`docs/book/src/**/*.md`, without what they include: `docs/claims.md` is checked on
/// its own), as (path relative to the repository, text).
fn documents() -> Vec<(String, String)> {
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
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut paths = vec![root.join("README.md"), root.join("ARCHITECTURE.md")];
    walk(&root.join("docs/book/src"), &mut paths);
    assert!(paths.len() > 12, "the user guide's chapters: {paths:?}");
    paths
        .into_iter()
        .map(|p| {
            let text = fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            let name = p.strip_prefix(&root).unwrap_or(&p).display().to_string();
            (name, text)
        })
        .collect()
}

/// The text under the heading `title` (of any level) in the one document that has it, up to
/// the next heading of that level or above.
fn section<'a>(documents: &'a [(String, String)], title: &str) -> &'a str {
    let level = |line: &str| line.len() - line.trim_start_matches('#').len();
    let is_title =
        |line: &str| level(line) > 0 && line[level(line)..].strip_prefix(' ') == Some(title);
    let holding: Vec<&(String, String)> = documents
        .iter()
        .filter(|(_, t)| t.lines().any(is_title))
        .collect();
    let names: Vec<&String> = holding.iter().map(|(n, _)| n).collect();
    assert_eq!(
        holding.len(),
        1,
        "exactly one document has the heading `{title}`: {names:?}"
    );
    let text = &holding[0].1;
    let (mut at, mut start) = (0, None);
    for l in text.split_inclusive('\n') {
        let line = l.trim_end();
        match start {
            None if is_title(line) => start = Some((at + l.len(), level(line))),
            Some((s, n))
                if (1..=n).contains(&level(line)) && line[level(line)..].starts_with(' ') =>
            {
                return &text[s..at];
            }
            _ => {}
        }
        at += l.len();
    }
    &text[start.unwrap().0..]
}

/// Every id of `docs/claims.md` with its verdict (each exactly once).
fn docs() -> BTreeMap<String, Verdict> {
    let mut out = BTreeMap::new();
    for c in citations(DOCS).expect("docs/claims.md cites every id with its verdict") {
        assert!(
            out.insert(c.id.clone(), c.verdict).is_none(),
            "docs/claims.md lists `{}` twice",
            c.id
        );
    }
    out
}

#[test]
fn registry_is_well_formed() {
    let claims = registry::claims();
    let mut ids = BTreeSet::new();
    for c in &claims {
        assert!(ids.insert(c.id), "duplicate id `{}`", c.id);
        assert!(
            is_claim_id(c.id),
            "`{}` is not of the form <source>-<digit>…",
            c.id
        );
        assert!(
            edgekf_io::reproductions::find(c.reproduction).is_some(),
            "`{}`: unknown reproduction `{}`",
            c.id,
            c.reproduction
        );
        for text in [c.statement, c.paper_value, c.location] {
            for w in ["agrees", "differs", "not checkable"] {
                assert!(!text.contains(w), "`{}`: its text contains `{w}`", c.id);
            }
        }
    }
    let papers = claims.iter().filter(|c| c.paper != Paper::Project).count();
    assert!(papers >= 50, "{papers} paper claims");
    for p in [Paper::Eusipco, Paper::Thesis, Paper::Guo, Paper::LiRajan] {
        assert!(claims.iter().any(|c| c.paper == p), "{p:?}");
    }
    // Every study exists and its scenario checks at both sizes.
    for s in edgekf_claims::needed_studies(&claims).unwrap() {
        if s.kind != edgekf_claims::study::Kind::Slam {
            s.scenario(Size::Full).unwrap();
            s.scenario(Size::Reduced).unwrap();
        }
    }
}

#[test]
fn docs_list_every_claim_and_the_guide_cites_their_verdicts() {
    let docs = docs();
    let ids: BTreeSet<String> = registry::claims()
        .iter()
        .map(|c| c.id.to_string())
        .collect();
    let listed: BTreeSet<String> = docs.keys().cloned().collect();
    assert_eq!(
        listed, ids,
        "docs/claims.md must list exactly the registry's claims"
    );
    let documents = documents();
    let mut count = 0;
    for (name, text) in &documents {
        let cited = citations(text)
            .unwrap_or_else(|e| panic!("{name} cites claims with their verdicts: {e}"));
        count += cited.len();
        for c in &cited {
            let d = docs
                .get(&c.id)
                .unwrap_or_else(|| panic!("{name} line {}: unknown claim `{}`", c.line, c.id));
            assert_eq!(
                c.verdict, *d,
                "{name} line {}: `{}` is cited as {} but the registry says {}",
                c.line, c.id, c.verdict, d
            );
        }
    }
    assert!(count >= 20, "{count} citations");
    // The guide's "could not confirm" chapter lists exactly the papers' claims that do not
    // agree.
    let section = section(&documents, SECTION);
    let in_section: BTreeSet<String> = citations(section)
        .unwrap()
        .into_iter()
        .map(|c| c.id)
        .collect();
    let expected: BTreeSet<String> = registry::claims()
        .iter()
        .filter(|c| c.paper != Paper::Project && docs[c.id] != Verdict::Agrees)
        .map(|c| c.id.to_string())
        .collect();
    assert_eq!(
        in_section, expected,
        "the section must list exactly the claims that differ or are not checkable"
    );
}

fn check(claims: Vec<Claim>, size: Size) {
    let docs = docs();
    let out = evaluate(&claims, Options { size, seeds: None }, &Silent).unwrap();
    let mut wrong = Vec::new();
    for o in &out {
        println!(
            "{:<50} {:>12} ± {:<10} {}",
            o.claim.id,
            o.estimate.map_or(f64::NAN, |e| e.value),
            o.estimate.map_or(f64::NAN, |e| e.se),
            o.verdict
        );
        if docs[o.claim.id] != o.verdict {
            wrong.push(format!(
                "`{}`: measured {} ({:?}), docs/claims.md says {}",
                o.claim.id, o.verdict, o.estimate, docs[o.claim.id]
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The claims already settled at reduced size (one seed, a few runs per study).
#[test]
fn settled_claims_at_reduced_size() {
    let small: Vec<Claim> = registry::claims().into_iter().filter(|c| c.small).collect();
    assert!(small.len() >= 30, "{} small claims", small.len());
    check(small, Size::Reduced);
}

/// Every claim at full size (as `edgekf claims`): ≈ 1–3 min on 2 cores in release mode.
#[test]
#[ignore = "full size: run with `cargo test --release -p edgekf-claims -- --ignored`"]
fn every_claim_at_full_size() {
    check(registry::claims(), Size::Full);
}

/// The README's introduction counts the registry's claims per paper (issue 25: it said 79 + 6
/// and "Li & Rajan not yet in the registry" when the registry held 30 of theirs and 8 of its own).
#[test]
fn readme_counts_are_the_registry_s() {
    let claims = registry::claims();
    let count = |p: Paper| claims.iter().filter(|c| c.paper == p).count();
    let (e, t, g, l, own) = (
        count(Paper::Eusipco),
        count(Paper::Thesis),
        count(Paper::Guo),
        count(Paper::LiRajan),
        count(Paper::Project),
    );
    let intro: String = README
        .split("## Two commands")
        .next()
        .unwrap()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    let expected = format!(
        "— {} of them (EUSIPCO {e}, thesis {t}, Guo et al. {g}, Li & Rajan {l}), and {own} of this README's own",
        e + t + g + l
    );
    assert!(
        intro.contains(&expected),
        "the README's intro should say: {expected}"
    );
    assert!(
        !intro.contains("not yet in the registry"),
        "stale sentence in the README's intro"
    );
}
