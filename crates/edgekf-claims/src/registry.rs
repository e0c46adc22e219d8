//! The registry: every claim, in paper order — as data. The claims are TOML files in the
//! crate's `claims/` directory, one per source (EUSIPCO 2022, the thesis, Guo et al. 2020, Li &
//! Rajan 2026, the README's own findings), embedded at build time and read once, at first use.
//!
//! # The format
//! Each file names its `paper` (`eusipco`, `thesis`, `guo`, `li_rajan`, `project`) and lists
//! its claims, one `[[claim]]` table each:
//!
//! ```toml
//! [[claim]]
//! id = "eusipco-4a-crkf-lowest"    # stable: <source>-<section or figure>-<slug>
//! where = "§4, Fig. 4a"            # where the paper says it
//! reproduction = "eusipco-fig4a"   # the figure it belongs to (`edgekf reproduce --list`)
//! claim = "the steady-state posterior covariance trace is lowest for the CRKF"
//! paper_value = "crkf < jrkf (ratio < 1)"
//! study = "eusipco"                # the simulation it is measured on (`studies.toml`)
//! stat.ratio = { metric = "cov_trace", num = "crkf", den = "jrkf", window = "steady" }
//! rule.below = 1.0                 # when it agrees
//! small = true                     # settled at reduced size (re-measured by `cargo test`)
//! ```
//!
//! - **Measure.** `study` and `stat` (a [`Statistic`]: its variant's name in snake case, with
//!   its fields); or `quotient = [{ study = …, stat.… = … }, { study = …, stat.… = … }]`, the
//!   quotient of two independent measurements; or neither (nothing to measure: the rule says
//!   why).
//! - **Rule** ([`Rule`]): `rule.below = x`, `rule.above = x`, `rule.at_most = x`,
//!   `rule.within = { lo, hi }`, `rule.outside = { lo, hi }`, `rule.near = { target, rel }`
//!   (within `target·(1 ± rel)`),
//!   `rule.factor = { target, factor }` (within `[target/factor, target·factor]`),
//!   `rule.matches = { printed, rounding }`, `rule.not_checkable = "why"`.
//! - **Windows** are `[from, to]` in seconds or a name of
//!   [`NAMED_WINDOWS`](crate::statistic::NAMED_WINDOWS): `"steady"` is 15–30 s for the
//!   estimation error and the covariance (the filters' floors are reached within a second),
//!   `"floor"` 25–30 s for the Procrustes error (the formation converges at ≈ 0.44 /s),
//!   `"early"` the transient 0.5–4 s, `"first"` the first reported step, `"whole"` 0.5–60 s of
//!   a GA-RKF run.
//! - **Strings** are borrowed from the embedded text, so they are written without escapes (a
//!   `'…'` literal string holds double quotes).
//!
//! Estimator labels are those of the shipped scenario files.

use std::sync::OnceLock;

use serde::Deserialize;

use crate::rule::Rule;
use crate::statistic::Statistic;
use crate::{Claim, Measure, Paper};

/// The claims files, in paper order.
const FILES: [(&str, &str); 5] = [
    ("eusipco.toml", include_str!("../claims/eusipco.toml")),
    ("thesis.toml", include_str!("../claims/thesis.toml")),
    ("guo.toml", include_str!("../claims/guo.toml")),
    ("garkf.toml", include_str!("../claims/garkf.toml")),
    ("project.toml", include_str!("../claims/project.toml")),
];

/// Why a claims file cannot be read (a bug of the shipped files: the tests read every one).
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The TOML does not parse into claims (the parser names the key and the line).
    #[error("claims/{file}: {error}")]
    Parse {
        /// The file.
        file: &'static str,
        /// The parser's error (in the message, so not a `source`).
        error: toml::de::Error,
    },
    /// A claim gives a study without a statistic, or both a study and a quotient.
    #[error("claims/{file}: claim `{id}`: give `study` and `stat`, or `quotient`, or neither (nothing to measure)")]
    Measure {
        /// The file.
        file: &'static str,
        /// The claim.
        id: &'static str,
    },
}

/// One claims file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, bound(deserialize = "'de: 'static"))]
struct File {
    paper: Paper,
    claim: Vec<Entry>,
}

/// One `[[claim]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    id: &'static str,
    #[serde(rename = "where")]
    location: &'static str,
    reproduction: &'static str,
    claim: &'static str,
    paper_value: &'static str,
    study: Option<&'static str>,
    stat: Option<Statistic>,
    quotient: Option<[On; 2]>,
    rule: RuleEntry,
    small: bool,
}

/// A statistic of one study (a term of a quotient).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct On {
    study: &'static str,
    stat: Statistic,
}

/// A [`Rule`] as written: its variants, and `near` and `factor` for [`Rule::near`] and
/// [`Rule::factor`].
#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum RuleEntry {
    Below(f64),
    Above(f64),
    AtMost(f64),
    Within { lo: f64, hi: f64 },
    Outside { lo: f64, hi: f64 },
    Near { target: f64, rel: f64 },
    Factor { target: f64, factor: f64 },
    Matches { printed: f64, rounding: f64 },
    NotCheckable(&'static str),
}

impl From<RuleEntry> for Rule {
    fn from(r: RuleEntry) -> Self {
        match r {
            RuleEntry::Below(x) => Rule::Below(x),
            RuleEntry::Above(x) => Rule::Above(x),
            RuleEntry::AtMost(x) => Rule::AtMost(x),
            RuleEntry::Within { lo, hi } => Rule::Within { lo, hi },
            RuleEntry::Outside { lo, hi } => Rule::Outside { lo, hi },
            RuleEntry::Near { target, rel } => Rule::near(target, rel),
            RuleEntry::Factor { target, factor } => Rule::factor(target, factor),
            RuleEntry::Matches { printed, rounding } => Rule::Matches { printed, rounding },
            RuleEntry::NotCheckable(why) => Rule::NotCheckable(why),
        }
    }
}

impl Entry {
    fn into_claim(self, file: &'static str, paper: Paper) -> Result<Claim, DataError> {
        let measure = match (self.study, self.stat, self.quotient) {
            (Some(study), Some(stat), None) => Measure::On { study, stat },
            (None, None, Some([a, b])) => Measure::Quotient(
                Box::new(Measure::on(a.study, a.stat)),
                Box::new(Measure::on(b.study, b.stat)),
            ),
            (None, None, None) => Measure::Nothing,
            _ => return Err(DataError::Measure { file, id: self.id }),
        };
        Ok(Claim {
            id: self.id,
            paper,
            location: self.location,
            statement: self.claim,
            paper_value: self.paper_value,
            reproduction: self.reproduction,
            measure,
            rule: self.rule.into(),
            small: self.small,
        })
    }
}

/// The claims of one file, in its order.
///
/// # Errors
/// [`DataError`] when the text is not a claims file.
fn parse(file: &'static str, text: &'static str) -> Result<Vec<Claim>, DataError> {
    let f: File = toml::from_str(text).map_err(|error| DataError::Parse { file, error })?;
    f.claim
        .into_iter()
        .map(|e| e.into_claim(file, f.paper))
        .collect()
}

/// Every claim of the shipped files, in paper order.
///
/// # Errors
/// [`DataError`] for a file that does not read.
pub fn load() -> Result<Vec<Claim>, DataError> {
    let mut all = Vec::new();
    for (file, text) in FILES {
        all.extend(parse(file, text)?);
    }
    Ok(all)
}

/// Every claim, in paper order: EUSIPCO 2022, the thesis (chapters 3–6, and §7.2 where it
/// speaks of chapter 5), Guo et al. 2020, Li & Rajan 2026, then the README's own findings.
///
/// # Panics
/// If a shipped claims file does not read ([`load`]; a bug the tests catch).
pub fn claims() -> Vec<Claim> {
    static ALL: OnceLock<Vec<Claim>> = OnceLock::new();
    ALL.get_or_init(|| load().unwrap_or_else(|e| panic!("{e}")))
        .clone()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_file_reads_and_errors_name_file_and_claim() {
        assert!(load().unwrap().len() >= 50);
        let text = "paper = \"guo\"\n[[claim]]\nid = \"guo-1-x\"\nwhere = \"§1\"\n\
                    reproduction = \"slam-fig3\"\nclaim = \"c\"\npaper_value = \"v\"\n\
                    study = \"slam-fig3\"\nrule.below = 1.0\nsmall = true\n";
        let e = parse("x.toml", text).unwrap_err();
        assert_eq!(
            e.to_string(),
            "claims/x.toml: claim `guo-1-x`: give `study` and `stat`, or `quotient`, or neither (nothing to measure)"
        );
        let bad = text.replace("rule.below", "rule.beneath");
        let e = parse("x.toml", Box::leak(bad.into_boxed_str())).unwrap_err();
        assert!(e.to_string().starts_with("claims/x.toml: "), "{e}");
        assert!(e.to_string().contains("beneath"), "{e}");
    }

    #[test]
    fn named_windows_read_as_their_spans() {
        let text = "paper = \"guo\"\n[[claim]]\nid = \"guo-1-x\"\nwhere = \"§1\"\n\
                    reproduction = \"slam-fig3\"\nclaim = \"c\"\npaper_value = \"v\"\n\
                    study = \"s\"\nstat.mean = { label = \"a\", metric = \"m\", window = \"steady\" }\n\
                    rule.near = { target = 1.0, rel = 0.5 }\nsmall = true\n";
        let c = parse("x.toml", text).unwrap();
        assert_eq!(
            c[0].measure,
            Measure::on(
                "s",
                Statistic::Mean {
                    label: "a",
                    metric: "m",
                    window: crate::statistic::STEADY
                }
            )
        );
        assert_eq!(c[0].rule, Rule::Within { lo: 0.5, hi: 1.5 });
        let bad = text.replace("\"steady\"", "\"stedy\"");
        let e = parse("x.toml", Box::leak(bad.into_boxed_str())).unwrap_err();
        assert!(e.to_string().contains("unknown window `stedy`"), "{e}");
    }
}
