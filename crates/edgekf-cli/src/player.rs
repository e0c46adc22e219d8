//! The report page's player: a section that animates the study's `frames.json` on a canvas
//! (`player.js`), self-contained like the rest of the page (the file gzipped and base64-encoded
//! into it).

use std::fmt::Write as _;
use std::fs;
use std::path::Path;

use std::io::Write as _;

use anyhow::{Context, Result};
use flate2::{write::GzEncoder, Compression};

const PLAYER_JS: &str = include_str!("player.js");

const PLAYER_STYLE: &str = "
#player canvas { width: 100%; max-width: 900px; height: auto; border: 1px solid #e3e3e3; display: block; }
#player .controls { display: flex; flex-wrap: wrap; gap: 0.4rem 1rem; align-items: center; margin: 0.5rem 0; font-size: 0.9rem; }
#player .controls input[type=range] { flex: 1 1 260px; }
#player button { min-width: 5rem; }
";

/// The player's section when the study wrote `frames.json` (`frames_listed`: whether it is one
/// of the study's files); a note when it did not.
pub fn section(o: &mut String, dir: &Path, frames_listed: bool) -> Result<()> {
    o.push_str("<h2 id=\"watch\">Watch the run</h2>\n");
    let path = dir.join("frames.json");
    if !frames_listed || !path.is_file() {
        o.push_str(
            "<p class=\"note\">No frames in this directory (a merged shard, a SLAM \
             study, or a study too large for the page's budget: see <code>frames.json</code> in \
             the formats).</p>\n",
        );
        return Ok(());
    }
    let json =
        fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let head: serde_json::Value = serde_json::from_str(&json)
        .with_context(|| format!("{}: not a frames file", path.display()))?;
    if head.get("schema").and_then(|v| v.as_str()) != Some("edgekf.frames/1") {
        anyhow::bail!("{}: schema is not edgekf.frames/1", path.display());
    }
    let _ = write!(
        o,
        "<style>{PLAYER_STYLE}</style>\n<div id=\"player\" data-frame=\"0\">\n\
         <canvas id=\"player-canvas\" width=\"900\" height=\"600\" tabindex=\"0\" role=\"img\" \
         aria-label=\"The formation at the chosen time: true positions, each agent's estimates of \
         its neighbours with 1σ ellipses\"></canvas>\n\
         <div class=\"controls\">\
         <button id=\"player-play\" type=\"button\" aria-pressed=\"false\">Play</button>\
         <input id=\"player-time\" type=\"range\" min=\"0\" max=\"0\" step=\"1\" value=\"0\" aria-label=\"Frame\">\
         <output id=\"player-clock\">t = 0 s</output>\
         <label>Speed <select id=\"player-speed\"><option value=\"0.25\">¼×</option>\
         <option value=\"0.5\">½×</option><option value=\"1\" selected>1×</option>\
         <option value=\"2\">2×</option><option value=\"4\">4×</option></select></label>\
         <label>Estimator <select id=\"player-est\"></select></label>\
         <label>Run <select id=\"player-run\"></select></label>\
         <label>View <select id=\"player-view\"></select></label>\
         <label>Ellipses <select id=\"player-scale\"><option value=\"1\" selected>1σ</option>\
         <option value=\"3\">3σ</option><option value=\"10\">10σ</option>\
         <option value=\"30\">30σ</option><option value=\"100\">100σ</option></select></label>\
         <a id=\"player-link\" href=\"#t=0\">link to this moment</a>\
         </div>\n\
         <p class=\"note\" id=\"player-status\">Discs: agents at their true positions (squares: \
         leaders; hollow grey: departed), with their paths so far. Thin coloured lines, dots \
         and ellipses: the estimated formation — each agent's estimate of a neighbour's \
         position, <i>z<sub>i</sub> − x̂<sub>ij</sub></i>, drawn from the agent, \
         and its 1σ ellipse (scalable: a filter's σ is often millimetres on a formation of metres), in \
         the owner's colour, drawn over the agents. Grey lines: links measured at \
         this step; red dashed: a link lost in either direction. Crosses: the target formation. \
         1× plays the run in 15 s. Keys: Space, ← →, Home, End. The link above points at the \
         moment shown (<code>#t=…&amp;run=…&amp;est=…</code>).</p>\n</div>\n\
         <script type=\"application/octet-stream\" id=\"frames-data\" \
         data-encoding=\"gzip+base64\">{}</script>\n\
         <script>{PLAYER_JS}</script>\n",
        crate::report::base64(&gzip(json.as_bytes())?)
    );
    Ok(())
}

/// `bytes` gzipped (the page's copy of `frames.json`: numbers as text compress 3–4×).
fn gzip(bytes: &[u8]) -> Result<Vec<u8>> {
    let mut gz = GzEncoder::new(Vec::new(), Compression::best());
    gz.write_all(bytes)?;
    Ok(gz.finish()?)
}
