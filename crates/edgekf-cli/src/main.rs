//! The `edgekf` command-line program.
mod plot;
mod slam;

// TEMPORARY wiring for the `slam` branch (the lead redoes main.rs with clap):
//   edgekf run FILE --out DIR
//   edgekf reproduce NAME... --out DIR
fn main() -> anyhow::Result<()> {
    plot::register_fonts();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out_pos = args
        .iter()
        .position(|a| a == "--out")
        .ok_or_else(|| anyhow::anyhow!("missing --out DIR"))?;
    let out = std::path::PathBuf::from(
        args.get(out_pos + 1)
            .ok_or_else(|| anyhow::anyhow!("missing DIR"))?,
    );
    let rest: Vec<&String> = args[..out_pos].iter().collect();
    match rest.first().map(|s| s.as_str()) {
        Some("run") => {
            let file = rest.get(1).ok_or_else(|| anyhow::anyhow!("missing FILE"))?;
            let text = std::fs::read_to_string(file.as_str())?;
            slam::run_text(file, &text, &out)
        }
        Some("reproduce") => {
            for name in &rest[1..] {
                let text = match name.as_str() {
                    "slam-fig3" => include_str!("../../../scenarios/slam-fig3.toml"),
                    "slam-disturbed" => include_str!("../../../scenarios/slam-disturbed.toml"),
                    other => anyhow::bail!("unknown reproduction {other}"),
                };
                slam::run_text(&format!("{name}.toml"), text, &out.join(name.as_str()))?;
            }
            Ok(())
        }
        _ => anyhow::bail!("usage: edgekf run FILE --out DIR | edgekf reproduce NAME... --out DIR"),
    }
}
