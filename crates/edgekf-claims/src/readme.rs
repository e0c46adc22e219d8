//! Claim citations in prose and tables (the README, `docs/claims.md`): every backticked claim id
//! followed, on the same line and before the next id, by its verdict word.
//!
//! A claim id is `<source>-<digit>…` with source `eusipco`, `thesis`, `guo`, `garkf` or
//! `project` (reproduction names such as `thesis-fig4.8` are not ids).

use crate::rule::Verdict;

/// Whether `s` has the form of a claim id.
pub fn is_claim_id(s: &str) -> bool {
    let Some((source, rest)) = s.split_once('-') else {
        return false;
    };
    ["eusipco", "thesis", "guo", "garkf", "project"].contains(&source)
        && rest.starts_with(|c: char| c.is_ascii_digit())
        && s.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '.')
}

/// One citation: the id, the verdict written next to it, and the line (1-based).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Citation {
    /// Claim id.
    pub id: String,
    /// The verdict stated.
    pub verdict: Verdict,
    /// Line number.
    pub line: usize,
}

/// Every citation of `text`.
///
/// # Errors
/// A message naming the line of an id cited without a verdict.
pub fn citations(text: &str) -> Result<Vec<Citation>, String> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        // Backticked spans: odd-numbered pieces between backticks.
        let pieces: Vec<&str> = line.split('`').collect();
        let mut ids: Vec<(usize, &str)> = Vec::new();
        let mut offset = 0;
        for (i, p) in pieces.iter().enumerate() {
            if i % 2 == 1 && is_claim_id(p) {
                ids.push((offset + p.len() + 1, p));
            }
            offset += p.len() + 1;
        }
        for (k, &(end, id)) in ids.iter().enumerate() {
            let stop = ids.get(k + 1).map_or(line.len(), |&(e, q)| e - q.len() - 1);
            let span = line
                .get(end.min(line.len())..stop.max(end).min(line.len()))
                .unwrap_or("");
            let found = ["not checkable", "agrees", "differs"]
                .iter()
                .filter_map(|w| span.find(w).map(|p| (p, *w)))
                .min();
            match found {
                Some((_, w)) => out.push(Citation {
                    id: id.to_string(),
                    verdict: Verdict::parse(w).expect("a verdict word"),
                    line: n + 1,
                }),
                None => {
                    return Err(format!(
                        "line {}: claim `{id}` is cited without its verdict (agrees, differs, not checkable)",
                        n + 1
                    ))
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_and_verdicts_are_found() {
        assert!(is_claim_id("thesis-4.8-rkf-floor-10x"));
        assert!(!is_claim_id("thesis-fig4.8"));
        assert!(!is_claim_id("eusipco"));
        let text = "The RKF is worse (`thesis-5.3-procrustes-rkf-below-mle`: differs), see \
                    `thesis-fig5.3`.\n| `guo-6-omega-positive` | Ω > 0 | 0.655 | agrees |\n\
                    both `eusipco-4a-crkf-lowest` agrees and `thesis-7.2-q-time-varying` is not checkable";
        let c = citations(text).unwrap();
        assert_eq!(c.len(), 4);
        assert_eq!(c[0].verdict, Verdict::Differs);
        assert_eq!(c[1].id, "guo-6-omega-positive");
        assert_eq!(c[1].line, 2);
        assert_eq!(c[2].verdict, Verdict::Agrees);
        assert_eq!(c[3].verdict, Verdict::NotCheckable);
        let e = citations("see `thesis-4.8-rkf-floor-10x` and nothing").unwrap_err();
        assert!(e.contains("line 1"), "{e}");
    }
}
