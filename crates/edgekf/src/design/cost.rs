//! The cost of a design, estimated before it runs, so that a size no machine can hold (a
//! complete graph on 100 000 agents has 5·10⁹ candidate links) is refused with the estimate
//! named instead of growing until the system kills it.
//!
//! The model counts what grows with the size: the candidate links (and their copies in the
//! graph and the framework), the dense N × N matrices of the checks (Laplacian, its
//! eigen-decomposition), the equilibrium basis of the stresses (a QR of the L × N·D rigidity
//! matrix), the interior-point method's L × L matrices and its `L² m` work per iteration, and
//! the generators' nearest-neighbour searches. The constants are calibrated on this project's
//! measurements (2 cores; `sdp` on 3 990 trilateration links at N = 1 000: 62 s, 760 MB peak);
//! the estimate is meant to tell seconds from hours and megabytes from terabytes, not to be
//! precise.

use super::{Method, AUTO_LINKS};

/// What a design will cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DesignCost {
    /// Bytes of memory at the peak.
    pub bytes: f64,
    /// Estimated wall time in seconds.
    pub seconds: f64,
}

impl DesignCost {
    fn plus(self, o: DesignCost) -> DesignCost {
        DesignCost {
            bytes: self.bytes.max(o.bytes),
            seconds: self.seconds + o.seconds,
        }
    }
}

/// Seconds per unit of the interior-point work `L² m` (measured: 62 s for L = 3 990,
/// m ≈ 1 990, 28 iterations).
const S_PER_IPM_UNIT: f64 = 2.5e-9;
/// Seconds per `N³` of a dense symmetric eigen-decomposition (nalgebra).
const S_PER_EIGEN_UNIT: f64 = 2e-9;
/// Seconds per floating-point operation of the other dense loops.
const S_PER_FLOP: f64 = 0.5e-9;
/// Bytes per candidate link, counting its copies (candidate list, graph, framework).
const BYTES_PER_LINK: f64 = 3.0 * 16.0;

/// How the candidate links come about (their count is known before they are generated).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Generation {
    /// Given (read from a file, or a fixed small generator).
    Given,
    /// Every agent linked to its nearest earlier (or all) agents: a search over the agents
    /// per agent, `O(N² log N)` (trilateration, backbone).
    Nearest,
    /// All pairs (complete).
    Complete,
}

/// Candidate links of the complete graph on `n` agents, without overflow.
pub fn complete_links(n: usize) -> f64 {
    let n = n as f64;
    n * (n - 1.0) / 2.0
}

/// Estimates generating `links` candidate links on `n` agents in `dim` dimensions
/// ([`Generation`]) and designing them with `method`, as [`super::design`] does (an SDP on a
/// nearest-neighbour subgraph, or the Yang construction, past [`AUTO_LINKS`] links).
pub fn estimate(
    n: usize,
    dim: usize,
    links: f64,
    generation: Generation,
    method: Method,
) -> DesignCost {
    let nf = n as f64;
    let d = dim.max(1) as f64;
    let complete = links >= complete_links(n) && n > 1;
    // Generating and holding the candidates.
    let gen = DesignCost {
        bytes: links * BYTES_PER_LINK + nf * (24.0 + 8.0 * d),
        seconds: match generation {
            Generation::Given => links * 20e-9,
            Generation::Nearest => nf * nf * (nf.max(2.0)).log2() * 2.5e-9,
            Generation::Complete => links * 5e-9,
        },
    };
    // The checks of every design: dense N × N matrices and their eigen-decompositions
    // (verification, the check report).
    let checks = DesignCost {
        bytes: links * BYTES_PER_LINK + 6.0 * 8.0 * nf * nf,
        seconds: 3.0 * S_PER_EIGEN_UNIT * nf * nf * nf,
    };
    // The stress SDP on `l` links: the equilibrium basis (QR of the L × N·D rigidity matrix) and
    // the interior-point method (three L × L matrices, L² m work).
    let sdp = |l: f64, passes: f64| {
        let m = (l - nf * d + d * (d + 1.0) / 2.0).max(1.0);
        DesignCost {
            bytes: links * BYTES_PER_LINK + 3.0 * 8.0 * l * l + 8.0 * l * nf * d,
            seconds: 2.0 * S_PER_FLOP * l * (nf * d) * (nf * d)
                + passes * S_PER_IPM_UNIT * l * l * m,
        }
    };
    let yang = DesignCost {
        bytes: links * BYTES_PER_LINK + 8.0 * 8.0 * nf * nf,
        seconds: S_PER_FLOP * nf * (d + 2.0).powi(3) * 10.0,
    };
    let work = match method {
        Method::Yang => yang,
        _ if complete && method == Method::Sdp => DesignCost {
            // Closed form: the projector onto the complement of span{1, P}.
            bytes: links * BYTES_PER_LINK + 4.0 * 8.0 * nf * nf,
            seconds: S_PER_FLOP * nf * nf * d,
        },
        Method::Sdp if links > AUTO_LINKS as f64 => {
            // A nearest-neighbour subgraph of at most AUTO_LINKS links, or Yang.
            let sub = (nf * (d + 2.0)).min(AUTO_LINKS as f64);
            if nf * (d + 2.0) > AUTO_LINKS as f64 {
                yang
            } else {
                sdp(sub, 1.0)
            }
        }
        Method::Sdp => sdp(links, 1.0),
        // Conditioning SDP, ℓ1 problem, polishing SDP.
        Method::Sparse => sdp(links, 3.0),
    };
    gen.plus(checks).plus(work)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_measured_design_is_minutes_and_the_huge_one_is_refusable() {
        // sdp on 3 990 trilateration links at N = 1 000: measured 62 s, 760 MB.
        let c = estimate(1000, 2, 3990.0, Generation::Nearest, Method::Sdp);
        assert!((30.0..300.0).contains(&c.seconds), "{c:?}");
        assert!((2e8..4e9).contains(&c.bytes), "{c:?}");
        // The thesis hexagon: instant.
        let c = estimate(10, 2, 30.0, Generation::Given, Method::Sdp);
        assert!(c.seconds < 0.1 && c.bytes < 1e6, "{c:?}");
        // The complete graph on 100 000 agents: terabytes and days.
        let n = 100_000;
        let c = estimate(n, 2, complete_links(n), Generation::Complete, Method::Sdp);
        assert!(c.bytes > 1e11 && c.seconds > 86_400.0, "{c:?}");
        // Random 50, complete candidates, sparse design: seconds.
        let c = estimate(
            50,
            2,
            complete_links(50),
            Generation::Complete,
            Method::Sparse,
        );
        assert!(c.seconds < 60.0, "{c:?}");
    }
}
