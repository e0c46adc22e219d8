//! Verdict rules: when a measured value agrees with what a paper says.
//!
//! A paper's ordering ("lower", "> 0") agrees when it holds by more than three standard errors;
//! a paper's approximate number agrees when the whole interval `value ± 3 SE` lies inside the
//! stated tolerance. Anything else differs — including a value that cannot be told apart from
//! the paper's boundary (the data do not confirm it). An exact quantity (SE 0) is compared
//! exactly. A claim without a measurement, or without an error where one is needed, is not
//! checkable, with the reason.

use std::fmt;

use serde::Serialize;

use crate::stats::Estimate;

/// How many standard errors a claim must hold by.
pub const SIGMAS: f64 = 3.0;

/// A verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Verdict {
    /// The paper's value or ordering holds (beyond 3 SE, or within the stated tolerance).
    #[serde(rename = "agrees")]
    Agrees,
    /// It does not.
    #[serde(rename = "differs")]
    Differs,
    /// It cannot be measured here (the reason goes with it).
    #[serde(rename = "not checkable")]
    NotCheckable,
}

impl Verdict {
    /// The word used in outputs and in the README: `agrees`, `differs`, `not checkable`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Agrees => "agrees",
            Verdict::Differs => "differs",
            Verdict::NotCheckable => "not checkable",
        }
    }

    /// Parses the word.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "agrees" => Some(Verdict::Agrees),
            "differs" => Some(Verdict::Differs),
            "not checkable" => Some(Verdict::NotCheckable),
            _ => None,
        }
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The rule a claim's measured value is judged by.
#[derive(Debug, Clone, PartialEq)]
pub enum Rule {
    /// The paper says the value is below `x`: agrees when `value + 3 SE < x`.
    Below(f64),
    /// The paper says the value is above `x`: agrees when `value − 3 SE > x`.
    Above(f64),
    /// The paper says `value ≤ x` (an exact identity, e.g. a zero difference): agrees when
    /// `value + 3 SE ≤ x`.
    AtMost(f64),
    /// An approximate number: agrees when `[value − 3 SE, value + 3 SE] ⊂ [lo, hi]`.
    Within {
        /// Lower end of the tolerance.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// The paper says the value is unlike a range (e.g. "unstable" against a rate called
    /// constant within ± 20 %): agrees when `[value − 3 SE, value + 3 SE]` misses `[lo, hi]`.
    Outside {
        /// Lower end of the range.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// A number the README prints, `printed` (to ± `rounding`, half a unit of its last digit):
    /// agrees when `|value − printed| ≤ 3 SE + rounding`.
    Matches {
        /// The printed number.
        printed: f64,
        /// Half a unit of its last printed digit.
        rounding: f64,
    },
    /// The claim cannot be measured here.
    NotCheckable(&'static str),
}

impl Rule {
    /// `≈ target` within a relative tolerance `rel` (`[target(1 − rel), target(1 + rel)]`).
    pub fn near(target: f64, rel: f64) -> Self {
        Rule::Within {
            lo: target * (1.0 - rel),
            hi: target * (1.0 + rel),
        }
    }

    /// `≈ target` within a factor `f` (`[target/f, target·f]`).
    pub fn factor(target: f64, f: f64) -> Self {
        Rule::Within {
            lo: target / f,
            hi: target * f,
        }
    }

    /// The verdict for a measurement, and why when it is not checkable.
    pub fn judge(&self, e: Option<Estimate>) -> (Verdict, Option<String>) {
        if let Rule::NotCheckable(why) = self {
            return (Verdict::NotCheckable, Some((*why).to_string()));
        }
        let Some(e) = e else {
            return (
                Verdict::NotCheckable,
                Some("no measurement (the study did not produce it)".into()),
            );
        };
        if !e.value.is_finite() {
            return (
                Verdict::NotCheckable,
                Some("the measured value is not finite (an estimator diverged?)".into()),
            );
        }
        if e.se.is_nan() {
            return (
                Verdict::NotCheckable,
                Some("no standard error: run more seeds (`--seeds 2` or more)".into()),
            );
        }
        let m = SIGMAS * e.se;
        let ok = match *self {
            Rule::Below(x) => e.value + m < x,
            Rule::Above(x) => e.value - m > x,
            Rule::AtMost(x) => e.value + m <= x,
            Rule::Within { lo, hi } => e.value - m >= lo && e.value + m <= hi,
            Rule::Outside { lo, hi } => e.value + m < lo || e.value - m > hi,
            Rule::Matches { printed, rounding } => (e.value - printed).abs() <= m + rounding,
            Rule::NotCheckable(_) => unreachable!(),
        };
        (
            if ok {
                Verdict::Agrees
            } else {
                Verdict::Differs
            },
            None,
        )
    }

    /// The rule in words, e.g. `< 1 by 3 SE`.
    pub fn describe(&self) -> String {
        match self {
            Rule::Below(x) => format!("< {} by {SIGMAS} SE", num(*x)),
            Rule::Above(x) => format!("> {} by {SIGMAS} SE", num(*x)),
            Rule::AtMost(x) => format!("≤ {}", num(*x)),
            Rule::Within { lo, hi } => format!("± {SIGMAS} SE inside [{}, {}]", num(*lo), num(*hi)),
            Rule::Outside { lo, hi } => {
                format!("± {SIGMAS} SE outside [{}, {}]", num(*lo), num(*hi))
            }
            Rule::Matches { printed, rounding } => {
                format!(
                    "{} (± {}) within {SIGMAS} SE",
                    num(*printed),
                    num(*rounding)
                )
            }
            Rule::NotCheckable(why) => format!("not checkable: {why}"),
        }
    }
}

/// A number in a short form.
pub fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x.abs() >= 1e-3 && x.abs() < 1e4 {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{x:.3e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(value: f64, se: f64) -> Option<Estimate> {
        Some(Estimate { value, se })
    }

    #[test]
    fn outside_needs_the_whole_interval_off_the_range() {
        let r = Rule::Outside { lo: 0.8, hi: 1.2 };
        assert_eq!(r.judge(est(0.5, 0.05)).0, Verdict::Agrees);
        assert_eq!(r.judge(est(1.5, 0.05)).0, Verdict::Agrees);
        // 0.7 ± 0.05: its interval reaches into the range.
        assert_eq!(r.judge(est(0.7, 0.05)).0, Verdict::Differs);
        assert_eq!(r.judge(est(1.0, 0.0)).0, Verdict::Differs);
    }

    #[test]
    fn orderings_need_three_standard_errors() {
        assert_eq!(Rule::Below(1.0).judge(est(0.9, 0.01)).0, Verdict::Agrees);
        // 1.004 ± 0.004 is not below 1: not confirmed, so it differs.
        assert_eq!(
            Rule::Below(1.0).judge(est(1.004, 0.004)).0,
            Verdict::Differs
        );
        assert_eq!(Rule::Below(1.0).judge(est(0.99, 0.004)).0, Verdict::Differs);
        assert_eq!(Rule::Above(0.0).judge(est(0.13, 0.04)).0, Verdict::Agrees);
        // Exact values compare exactly.
        assert_eq!(Rule::Below(1.0).judge(est(0.999, 0.0)).0, Verdict::Agrees);
        assert_eq!(Rule::AtMost(0.0).judge(est(0.0, 0.0)).0, Verdict::Agrees);
        assert_eq!(Rule::AtMost(0.0).judge(est(1e-15, 0.0)).0, Verdict::Differs);
    }

    #[test]
    fn tolerances_hold_the_whole_interval() {
        let r = Rule::factor(10.0, 1.5);
        assert_eq!(r.judge(est(8.8, 0.3)).0, Verdict::Agrees);
        assert_eq!(r.judge(est(8.8, 0.8)).0, Verdict::Differs);
        assert_eq!(r.judge(est(2.7, 0.1)).0, Verdict::Differs);
        let (v, why) = r.judge(est(8.8, f64::NAN));
        assert_eq!(v, Verdict::NotCheckable);
        assert!(why.unwrap().contains("seeds"));
        assert_eq!(
            Rule::NotCheckable("x").judge(None),
            (Verdict::NotCheckable, Some("x".into()))
        );
    }
}
