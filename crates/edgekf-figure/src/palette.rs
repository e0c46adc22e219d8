//! Colour-blind-safe colours.
//!
//! - [`series`]: the Okabe–Ito palette (Okabe & Ito, *Color Universal Design*, 2008) without its yellow, which is
//!   too pale on white: for estimators and other curves compared in one figure.
//! - [`agent`]: Paul Tol's "muted" qualitative palette (nine colours, all clearly chromatic), then the same colours
//!   dashed: for agent and robot paths. None of them is grey or black, which are reserved for [`LINK`] (final
//!   links), [`MARKER`] (start/end markers, true landmarks) and [`LEADER`] — so no path can share a colour with
//!   the links or markers drawn over it (thesis Fig. 3.4 once had an agent's path in the links' grey).

use super::raster::Rgb;
use super::Dash;

/// Okabe–Ito: blue, vermillion, bluish green, reddish purple, orange, sky blue, black.
pub const SERIES: [Rgb; 7] = [
    Rgb(0, 114, 178),
    Rgb(213, 94, 0),
    Rgb(0, 158, 115),
    Rgb(204, 121, 167),
    Rgb(230, 159, 0),
    Rgb(86, 180, 233),
    Rgb(0, 0, 0),
];

/// Paul Tol's muted palette: rose, indigo, sand, green, cyan, wine, teal, olive, purple.
pub const AGENTS: [Rgb; 9] = [
    Rgb(204, 102, 119),
    Rgb(51, 34, 136),
    Rgb(221, 204, 119),
    Rgb(17, 119, 51),
    Rgb(136, 204, 238),
    Rgb(136, 34, 85),
    Rgb(68, 170, 153),
    Rgb(153, 153, 51),
    Rgb(170, 68, 153),
];

/// Final links of a formation: neutral grey, never an agent colour.
pub const LINK: Rgb = Rgb(140, 140, 140);
/// Markers (start and end positions, true landmarks): black.
pub const MARKER: Rgb = Rgb(0, 0, 0);
/// Leaders' markers: a red that no agent colour is close to.
pub const LEADER: Rgb = Rgb(220, 0, 0);
/// Axis frame and tick marks.
pub const AXIS: Rgb = Rgb(40, 40, 40);
/// Grid lines.
pub const GRID: Rgb = Rgb(226, 226, 226);
/// Secondary text (notes).
pub const NOTE: Rgb = Rgb(90, 90, 90);

/// Colour of the k-th curve of a figure.
pub fn series(k: usize) -> Rgb {
    SERIES[k % SERIES.len()]
}

/// Colour and dash of the k-th agent's path: the nine muted colours solid, then dashed, then dotted.
pub fn agent(k: usize) -> (Rgb, Dash) {
    let dash = match (k / AGENTS.len()) % 3 {
        0 => Dash::Solid,
        1 => Dash::Dashed,
        _ => Dash::Dotted,
    };
    (AGENTS[k % AGENTS.len()], dash)
}

/// Chroma (max − min channel), 0 for greys.
pub fn chroma(c: Rgb) -> u8 {
    let (a, b) = (c.0.max(c.1).max(c.2), c.0.min(c.1).min(c.2));
    a - b
}

/// Euclidean distance in RGB.
pub fn distance(a: Rgb, b: Rgb) -> f64 {
    let d = |x: u8, y: u8| (f64::from(x) - f64::from(y)).powi(2);
    (d(a.0, b.0) + d(a.1, b.1) + d(a.2, b.2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agent_colours_never_look_like_links_or_markers() {
        for k in 0..30 {
            let (c, _) = agent(k);
            assert!(chroma(c) >= 60, "agent {k}: {c:?} is nearly grey");
            for reserved in [LINK, MARKER, LEADER, Rgb::WHITE] {
                assert!(
                    distance(c, reserved) > 70.0,
                    "agent {k}: {c:?} close to {reserved:?}"
                );
            }
        }
        // Within the first nine agents, colours are distinct.
        for i in 0..9 {
            for j in 0..i {
                assert!(distance(agent(i).0, agent(j).0) > 50.0);
            }
        }
    }
}
