//! `edgekf run` / `edgekf reproduce` for the distributed SLAM observer of Guo et al. (IFAC 2020), schema
//! `edgekf.slam/1`: parse and validate the scenario, print the design checks, simulate, and write
//! `scenario.json`, `robots.csv`, `team.csv`, `paths.png` (Fig. 3 style) and `errors.png`.

#[path = "slam_plot.rs"]
mod slam_plot;

use anyhow::{anyhow, bail, Context, Result};
use edgekf_slam::observer::printed_care;
use edgekf_slam::{simulate, Scenario, ScenarioSpec, Trajectory, KIND, SCHEMA};
use std::fmt::Write as _;
use std::path::Path;

/// The `name` of a SLAM scenario (what its output directory is recognised by).
///
/// # Errors
/// A text that does not parse, with the message of [`run_text`].
pub fn study_name(source: &str, text: &str) -> Result<String> {
    Ok(parse(source, text)?.name)
}

/// Runs a SLAM scenario given as TOML (`kind = "slam"`) or as a resolved `scenario.json`
/// (`"schema": "edgekf.slam/1"`, detected by a leading `{`), and stages every output for `out`;
/// the caller commits them, with `provenance.json`.
///
/// `source` names the input in error messages. Nothing is created before the scenario is valid
/// and simulated; each output is staged under a temporary name and moved into place only when
/// all of them are written, so an error leaves nothing under an output name.
///
/// The design checks go to stderr (a log); the final summary to stdout, as JSON with `json`.
pub fn run_text(source: &str, text: &str, out: &Path, json: bool) -> Result<edgekf_io::Staged> {
    let spec = parse(source, text)?;
    let sc = spec.validate().map_err(|e| anyhow!("{source}: {e}"))?;
    eprint!("{}", design_report(source, &sc));
    let started = std::time::Instant::now();
    let traj = simulate(&sc);
    let elapsed = started.elapsed();
    let resolved = resolved_json(&sc)?;
    let mut st = crate::interrupt::stage(out)?;
    st.write("scenario.json", resolved.as_bytes())?;
    st.write("robots.csv", robots_csv(&sc, &traj).as_bytes())?;
    st.write("team.csv", team_csv(&sc, &traj).as_bytes())?;
    plot_staged(&mut st, out, "paths.png", |p| {
        slam_plot::paths(p, &sc, &traj)
    })?;
    plot_staged(&mut st, out, "errors.png", |p| {
        slam_plot::errors(p, &sc, &traj)
    })?;
    if json {
        println!("{}", summary_json(&sc, &traj));
    } else {
        print!("{}", final_report(&sc, &traj, elapsed));
    }
    eprintln!(
        "wrote {}/{{scenario.json, robots.csv, team.csv, paths.png, errors.png}}",
        out.display()
    );
    Ok(st)
}

/// The final errors as JSON (for scripts).
fn summary_json(sc: &Scenario, tr: &Trajectory) -> String {
    let k = tr.times.len() - 1;
    let t = tr.times[k];
    let x = &tr.x[k];
    let peak = (0..=k).map(|j| tr.total_error(j)).fold(0.0, f64::max);
    let v = serde_json::json!({
        "scenario": sc.name(),
        "time": t,
        "est_err_total": tr.total_error(k),
        "est_err_total_peak": peak,
        "formation_err": sc.formation_error(x),
        "centroid_err": sc.centroid_error(t, x),
        "robots": (0..sc.n()).map(|i| tr.error(k, i).norm()).collect::<Vec<f64>>(),
    });
    serde_json::to_string_pretty(&v).unwrap_or_default()
}

fn parse(source: &str, text: &str) -> Result<ScenarioSpec> {
    if text.trim_start().starts_with('{') {
        let spec: ScenarioSpec =
            serde_json::from_str(text).map_err(|e| anyhow!("{source}: {e}"))?;
        match spec.schema.as_deref() {
            Some(SCHEMA) => Ok(spec),
            Some(other) => bail!("{source}: key `schema` must be \"{SCHEMA}\", found \"{other}\""),
            None => bail!("{source}: key `schema` is missing (a resolved SLAM scenario has \"schema\": \"{SCHEMA}\")"),
        }
    } else {
        let spec = ScenarioSpec::from_toml(text)
            .map_err(|e| anyhow!("{source}: {}", e.to_string().trim_end()))?;
        match spec.kind.as_deref() {
            Some(KIND) => Ok(spec),
            Some(other) => bail!("{source}: key `kind` must be \"{KIND}\", found \"{other}\""),
            None => bail!(
                "{source}: key `kind` is missing (a SLAM scenario starts with kind = \"{KIND}\")"
            ),
        }
    }
}

/// The resolved scenario as JSON, checked to parse back to the identical spec (so a re-run reproduces the CSVs).
fn resolved_json(sc: &Scenario) -> Result<String> {
    let mut json = edgekf_io::to_json_pretty(sc.resolved())
        .context("cannot serialise the resolved scenario")?;
    json.push('\n');
    let back: ScenarioSpec =
        serde_json::from_str(&json).context("the resolved scenario does not parse back")?;
    if &back != sc.resolved() {
        bail!(
            "scenario.json would not reproduce the run: a number does not survive the JSON round trip \
             (enable serde_json's `float_roundtrip` feature)"
        );
    }
    Ok(json)
}

fn plot_staged(
    st: &mut edgekf_io::Staged,
    out: &Path,
    name: &str,
    draw: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    // The staged name keeps the `.png` extension: the bitmap backend picks the encoder from it.
    let tmp = st.path(name);
    draw(&tmp).with_context(|| format!("cannot draw {}", out.join(name).display()))
}

fn norm2(a: f64, b: f64) -> f64 {
    (a * a + b * b).sqrt()
}

fn robots_csv(sc: &Scenario, tr: &Trajectory) -> String {
    let (n, m) = (sc.n(), sc.m());
    let mut s = String::with_capacity(tr.times.len() * n * (4 * (n + m) + 3) * 40);
    s.push_str("time,robot,quantity,value\n");
    for (k, &t) in tr.times.iter().enumerate() {
        let x = &tr.x[k];
        for i in 0..n {
            let xh = &tr.xhat[k][i];
            let mut row = |q: &str, v: f64| {
                let _ = writeln!(s, "{t},{i},{q},{v}");
            };
            row("px", x[2 * i]);
            row("py", x[2 * i + 1]);
            for j in 0..n {
                row(&format!("est_p{j}_x"), xh[2 * j]);
                row(&format!("est_p{j}_y"), xh[2 * j + 1]);
            }
            for l in 0..m {
                row(&format!("est_m{l}_x"), xh[2 * (n + l)]);
                row(&format!("est_m{l}_y"), xh[2 * (n + l) + 1]);
            }
            for j in 0..n {
                row(
                    &format!("err_p{j}"),
                    norm2(xh[2 * j] - x[2 * j], xh[2 * j + 1] - x[2 * j + 1]),
                );
            }
            for l in 0..m {
                let c = 2 * (n + l);
                row(
                    &format!("err_m{l}"),
                    norm2(xh[c] - x[c], xh[c + 1] - x[c + 1]),
                );
            }
            row("est_err", (xh - x).norm());
        }
    }
    s
}

fn team_csv(sc: &Scenario, tr: &Trajectory) -> String {
    let mut s = String::with_capacity(tr.times.len() * 5 * 40);
    s.push_str("time,quantity,value\n");
    for (k, &t) in tr.times.iter().enumerate() {
        let x = &tr.x[k];
        let pc = sc.centroid(x);
        for (q, v) in [
            ("pc_x", pc[0]),
            ("pc_y", pc[1]),
            ("centroid_err", sc.centroid_error(t, x)),
            ("formation_err", sc.formation_error(x)),
            ("est_err_total", tr.total_error(k)),
        ] {
            let _ = writeln!(s, "{t},{q},{v}");
        }
    }
    s
}

fn design_report(source: &str, sc: &Scenario) -> String {
    let mut s = String::new();
    let (n, m) = (sc.n(), sc.m());
    let _ = writeln!(
        s,
        "{} ({source}): n = {n} robots, m = {m} landmarks, state dimension N = {}",
        sc.name(),
        2 * (n + m)
    );
    let _ = writeln!(
        s,
        "CARE (eq. 20) with the design weight Z_iᵀ Q Z_i, Q = {} I, R_i = r_i I:",
        sc.q()
    );
    for (i, ob) in sc.observers().iter().enumerate() {
        let c = &ob.care;
        let _ = writeln!(
            s,
            "  robot {i}: r_i = {:>2}, residual ‖·‖_F = {:.2e} (relative {:.2e}, {} Newton step(s)), P̄ > 0: {} (λ_min = {:.4}), Ā¹¹ − K̄H̄ Hurwitz: {} (abscissa {:.4})",
            ob.observable_dim(),
            c.residual,
            c.relative_residual,
            c.newton_steps,
            if c.min_eig > 0.0 { "yes" } else { "NO" },
            c.min_eig,
            if c.closed_loop_abscissa < 0.0 { "yes" } else { "NO" },
            c.closed_loop_abscissa
        );
    }
    let _ = writeln!(s, "CARE as printed (Ḡ_i = Z_iᵀ G, G = [I_2n; 0]):");
    for (i, ob) in sc.observers().iter().enumerate() {
        let pc = printed_care(sc.model(), ob, sc.q());
        let verdict = match &pc.result {
            Ok(_) => "has a stabilising solution".to_string(),
            Err(e) => format!("{e}"),
        };
        let _ = writeln!(
            s,
            "  robot {i}: {} Hamiltonian eigenvalues with |Re λ| ≤ 1e-6‖𝓗‖ (closest Re λ = {:.1e}): {verdict}",
            pc.on_axis, pc.closest_eigenvalue.re
        );
    }
    theorem_report(&mut s, sc);
    let rho = sc.closed_loop_spectral_radius();
    let _ = writeln!(
        s,
        "RK4: h = {} s, {} steps, output every {} steps; closed-loop spectral radius ρ = {:.3} /s, hρ = {:.2e}",
        sc.step(),
        sc.steps(),
        sc.output_stride(),
        rho,
        sc.step() * rho
    );
    s
}

/// Theorem 1's conditions (eqs. 24–25), its witness and 𝕄, and the error system's stability.
fn theorem_report(s: &mut String, sc: &Scenario) {
    let r = sc.theorem1();
    let _ = writeln!(
        s,
        "Theorem 1 (eq. 24 with −1/δ; the paper's +1/δ would make it hold for any gains):"
    );
    let _ = writeln!(
        s,
        "  (24): sup_δ λ_min Ω(δ) = λ_min Ω(∞) = {:.4} → {}",
        r.zeta_sup,
        if r.condition24 {
            "holds for large enough δ"
        } else {
            "FAILS for every δ > 0"
        }
    );
    let _ = writeln!(
        s,
        "  λ_min = {:.4}, ξ = {:.4}, γ = {}",
        r.lambda_min, r.xi, r.gamma
    );
    let _ = writeln!(
        s,
        "  (25): sup_δ,τ ζ_min(γλ_min − 1/(2τ)) − γ²ξ²/4 = {:.4} → {}",
        r.condition25_sup,
        if r.condition25 { "holds" } else { "FAILS" }
    );
    match r.witness {
        Some((d, t)) => {
            let _ = writeln!(s, "  witness δ = {d}, τ = {t}");
        }
        None => {
            let _ = writeln!(
                s,
                "  (no δ, τ satisfy (24)–(25); 𝕄 below is the limit δ, τ → ∞)"
            );
        }
    }
    let mm = r.m_matrix;
    let _ = writeln!(
        s,
        "  𝕄 = [[{:.4}, {:.4}], [{:.4}, {:.4}]], λ_min(𝕄) = {:.4}",
        mm[(0, 0)],
        mm[(0, 1)],
        mm[(1, 0)],
        mm[(1, 1)],
        mm.symmetric_eigenvalues().min()
    );
    let _ = writeln!(
        s,
        "  error system (eq. 21): spectral abscissa {:.4} → {}; with eq. (10)'s consensus sign: {:+.4}",
        r.error_abscissa,
        if r.error_abscissa < 0.0 { "Hurwitz, the errors converge" } else { "NOT Hurwitz" },
        r.error_abscissa_eq10
    );
}

fn final_report(sc: &Scenario, tr: &Trajectory, elapsed: std::time::Duration) -> String {
    let k = tr.times.len() - 1;
    let t = tr.times[k];
    let x = &tr.x[k];
    let mut s = String::new();
    let _ = writeln!(
        s,
        "simulated {} s in {:.1} ms",
        t,
        elapsed.as_secs_f64() * 1e3
    );
    let peak = (0..=k).map(|j| tr.total_error(j)).fold(0.0, f64::max);
    let _ = writeln!(
        s,
        "final (t = {t} s): est_err_total = {:.3e} (peak {:.3e}), formation_err = {:.3e}, centroid_err = {:.3e}",
        tr.total_error(k),
        peak,
        sc.formation_error(x),
        sc.centroid_error(t, x)
    );
    for i in 0..sc.n() {
        let _ = writeln!(s, "  robot {i}: est_err = {:.3e}", tr.error(k, i).norm());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIG3: &str = include_str!("../../../scenarios/slam-fig3.toml");

    fn temp_dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("edgekf-slam-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// `run_text` into `out`, committed.
    fn run_into(source: &str, text: &str, out: &Path) -> Result<()> {
        Ok(run_text(source, text, out, false)?.commit()?)
    }

    /// A 1 s horizon keeps the test fast; exactness of the round trip does not depend on the horizon.
    fn short() -> String {
        FIG3.replace("horizon = 10.0", "horizon = 1.0")
    }

    #[test]
    fn json_round_trip_reproduces_the_csvs_exactly() {
        let (a, b) = (temp_dir("a"), temp_dir("b"));
        run_into("short.toml", &short(), &a).unwrap();
        let json = std::fs::read_to_string(a.join("scenario.json")).unwrap();
        run_into("scenario.json", &json, &b).unwrap();
        for f in ["scenario.json", "robots.csv", "team.csv"] {
            assert_eq!(
                std::fs::read(a.join(f)).unwrap(),
                std::fs::read(b.join(f)).unwrap(),
                "{f}"
            );
        }
        let team = std::fs::read_to_string(a.join("team.csv")).unwrap();
        assert!(team.starts_with("time,quantity,value\n0,pc_x,0.3333333333333333\n"));
        // 51 samples (1 s on the 20 ms grid) × 5 quantities + header.
        assert_eq!(team.lines().count(), 1 + 51 * 5);
        let robots = std::fs::read_to_string(a.join("robots.csv")).unwrap();
        // per robot: 2 + 2n + 2m + n + m + 1 = 27 quantities.
        assert_eq!(robots.lines().count(), 1 + 51 * 3 * 27);
        assert!(robots.lines().nth(1).unwrap() == "0,0,px,0");
        for d in [a, b] {
            let _ = std::fs::remove_dir_all(d);
        }
    }

    #[test]
    fn errors_name_the_file_the_key_and_the_condition() {
        let out = temp_dir("err");
        let e = run_into("bad.toml", &short().replace("kind = \"slam\"\n", ""), &out).unwrap_err();
        assert!(
            e.to_string().starts_with("bad.toml: key `kind` is missing"),
            "{e}"
        );
        let e = run_into(
            "bad.toml",
            &short().replace("k1 = 1.0", "k1 = 1.0\nk9 = 1.0"),
            &out,
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with("bad.toml: ") && e.to_string().contains("unknown field `k9`"),
            "{e}"
        );
        let bad = short().replace(
            "measurement = [[1.0, -1.0, 0.0]",
            "measurement = [[1.0, -2.0, 0.0]",
        );
        let e = run_into("bad.toml", &bad, &out).unwrap_err();
        assert_eq!(
            e.to_string(),
            "bad.toml: key `graphs.measurement` is not a graph Laplacian: row 0 sums to -1, not 0"
        );
        let e = run_into("s.json", "{\"name\": \"x\"}", &out).unwrap_err();
        assert!(e.to_string().starts_with("s.json: "), "{e}");
        // Nothing was written for the failed runs.
        assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
    }
}
