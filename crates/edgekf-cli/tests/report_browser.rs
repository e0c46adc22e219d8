//! The report pages as a reader's browser shows them: headless Chromium loads each page of a
//! small `reproduce --report` (a filter study with a fixture `claims.json`, a SLAM study without
//! one, and the index), and the test fails on a script error, a console message, an image that
//! does not decode, an empty table, or a page that needs the network. A page with a broken
//! image, a script error and an empty table is checked too, so the detection itself is tested.
//! A screenshot of the filter study's page is written to
//! `target/tmp/report-page.png`.
//!
//! Needs Debian's `chromium` (or `EDGEKF_CHROMIUM=/path/to/chrome`); `.ci/run` installs it and
//! runs this test with `--ignored`:
//!
//! ```sh
//! cargo test -p edgekf-cli --test report_browser -- --ignored
//! ```

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn edgekf(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_edgekf"))
        .args(args)
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "edgekf {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn chromium() -> PathBuf {
    if let Ok(p) = std::env::var("EDGEKF_CHROMIUM") {
        return PathBuf::from(p);
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        if let Ok(o) = Command::new("which").arg(name).output() {
            if o.status.success() {
                return PathBuf::from(String::from_utf8_lossy(&o.stdout).trim().to_string());
            }
        }
    }
    panic!(
        "no headless browser: install Debian's `chromium` (apt-get install -y chromium; .ci/run \
         does) or set EDGEKF_CHROMIUM"
    );
}

/// Runs headless Chromium on `page` with `extra` flags; returns (stdout, stderr).
fn browse(page: &Path, extra: &[String]) -> (String, String) {
    browse_at(page, "", extra)
}

/// [`browse`] at `page` + `fragment` (e.g. `#t=1.5`).
fn browse_at(page: &Path, fragment: &str, extra: &[String]) -> (String, String) {
    let profile = std::env::temp_dir().join(format!(
        "edgekf-chromium-{}-{}",
        std::process::id(),
        Instant::now().elapsed().as_nanos()
    ));
    let _ = fs::remove_dir_all(&profile);
    fs::create_dir_all(&profile).unwrap();
    let url = format!(
        "file://{}{fragment}",
        page.canonicalize().unwrap().display()
    );
    let mut cmd = Command::new(chromium());
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
        "--enable-logging=stderr",
        "--v=0",
        "--virtual-time-budget=10000",
    ])
    .arg(format!("--user-data-dir={}", profile.display()))
    .args(extra)
    .arg(&url)
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("chromium starts");
    let (mut out, mut err) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let t_out = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut out, &mut s).ok();
        s
    });
    let t_err = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut err, &mut s).ok();
        s
    });
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("chromium did not finish {url} within 60 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = fs::remove_dir_all(&profile);
    (t_out.join().unwrap(), t_err.join().unwrap())
}

/// The `#selfcheck` element's attributes after load.
struct Check {
    status: String,
    images: usize,
    broken: usize,
    tables: usize,
    empty: usize,
    errors: usize,
    dom: String,
    console: Vec<String>,
}

fn attr(tag: &str, name: &str) -> Option<String> {
    let key = format!("{name}=\"");
    let i = tag.find(&key)? + key.len();
    let j = tag[i..].find('"')? + i;
    Some(tag[i..j].to_string())
}

fn check(page: &Path) -> Check {
    let (dom, err) = browse(page, &["--dump-dom".to_string()]);
    let i = dom
        .find("id=\"selfcheck\"")
        .unwrap_or_else(|| panic!("{}: no #selfcheck in the DOM:\n{dom}", page.display()));
    let start = dom[..i].rfind('<').unwrap();
    let end = dom[i..].find('>').unwrap() + i;
    let tag = &dom[start..=end];
    let num = |n: &str| {
        attr(tag, n)
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{}: {n} missing in {tag}", page.display()))
    };
    // Chromium logs every console message (and uncaught exceptions) as `…:CONSOLE…] "…"`.
    let console = err
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(String::from)
        .collect();
    Check {
        status: attr(tag, "data-status").unwrap_or_default(),
        images: num("data-images"),
        broken: num("data-broken-images"),
        tables: num("data-tables"),
        empty: num("data-empty-tables"),
        errors: num("data-errors"),
        dom,
        console,
    }
}

fn assert_clean(page: &Path, c: &Check, images: usize, tables: usize) {
    let p = page.display();
    assert_eq!(c.status, "ok", "{p}: self-check failed");
    assert_eq!(c.errors, 0, "{p}: script errors");
    assert_eq!(c.broken, 0, "{p}: images that do not decode");
    assert_eq!(c.empty, 0, "{p}: empty tables");
    assert!(
        c.images >= images,
        "{p}: {} images, expected {images}",
        c.images
    );
    assert!(
        c.tables >= tables,
        "{p}: {} tables, expected {tables}",
        c.tables
    );
    assert!(c.console.is_empty(), "{p}: console output {:?}", c.console);
    // Self-contained: every src/href is inline data, an anchor, or a file beside the page.
    let html = fs::read_to_string(page).unwrap();
    for key in ["src=\"", "href=\""] {
        for (i, _) in html.match_indices(key) {
            let v = &html[i + key.len()..];
            let v = &v[..v.find('"').unwrap()];
            let local = v.starts_with("data:image/png;base64,")
                || v.starts_with('#')
                || !(v.contains("://") || v.starts_with('/'));
            assert!(local, "{p}: refers to `{}`", &v[..v.len().min(60)]);
        }
    }
    for bad in ["@import", "url(", "<link"] {
        assert!(!html.contains(bad), "{p}: contains `{bad}`");
    }
}

const CLAIMS: &str = r#"[
  {"id": "fig3.3-converges", "paper": "thesis", "where": "§3.5, Fig. 3.3", "claim": "Procrustes error decreases exponentially", "paper_value": "exponential decay", "value": 0.44, "se": 0.01, "verdict": "agrees"},
  {"id": "fig3.3-rate", "paper": "thesis", "where": "§3.5", "claim": "rate 1 /s", "paper_value": 1.0, "value": 0.44, "se": 0.01, "verdict": "differs"},
  {"id": "fig3.3-weights", "paper": "thesis", "where": "§3.4", "claim": "the printed weights", "paper_value": null, "value": null, "se": null, "verdict": "not checkable"}
]"#;

#[test]
#[ignore = "needs headless Chromium; .ci/run installs it and runs this with --ignored"]
fn report_pages_render_in_chromium_without_errors() {
    let t0 = Instant::now();
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-browser");
    let _ = fs::remove_dir_all(&root);
    let out = root.to_str().unwrap();
    edgekf(&[
        "reproduce",
        "eusipco-fig3",
        "thesis-fig3.3",
        "thesis-fig3.4",
        "slam-disturbed",
        "--runs",
        "2",
        "--steps",
        "600",
        "--out",
        out,
        "--report",
    ]);
    // The claims interface: `edgekf claims … --json > DIR/claims.json`, then `edgekf report`.
    fs::write(root.join("thesis-fig3.3/claims.json"), CLAIMS).unwrap();
    edgekf(&["report", out]);

    let filters = root.join("thesis-fig3.3/report.html");
    let c = check(&filters);
    assert_clean(&filters, &c, 2, 3);
    for id in ["fig3.3-converges", "fig3.3-rate", "fig3.3-weights"] {
        assert!(c.dom.contains(id), "claim {id} not shown");
    }
    assert!(c.dom.contains("1 agree, 1 differ, 1 not checkable"));

    let slam = root.join("slam-disturbed/report.html");
    let c = check(&slam);
    assert_clean(&slam, &c, 2, 2);
    assert!(c.dom.contains("No claims checked for this study"));

    let index = root.join("index.html");
    let c = check(&index);
    assert_clean(&index, &c, 0, 2);
    assert!(c.dom.contains("thesis-fig3.3/report.html#thesis-fig3.4"));

    // The detection works: a broken image, a script error and an empty table are all caught.
    let html = fs::read_to_string(&filters).unwrap();
    let broken = html
        .replacen(
            "data:image/png;base64,iVBOR",
            "data:image/png;base64,AAAA",
            1,
        )
        .replacen(
            "</footer>",
            "</footer><script>no_such_function();</script><table id=\"void\"><tbody></tbody></table>",
            1,
        );
    let bad = root.join("thesis-fig3.3/broken.html");
    fs::write(&bad, broken).unwrap();
    let c = check(&bad);
    assert_eq!(c.status, "fail");
    assert_eq!(c.broken, 1);
    assert!(c.errors >= 1);
    assert_eq!(c.empty, 1);
    assert!(
        !c.console.is_empty(),
        "the uncaught error reaches the console log"
    );

    // The player on a study of several estimators.
    let eusipco = root.join("eusipco/report.html");
    player_plays_scrubs_and_follows_links(&eusipco, &root.join("eusipco/frames.json"));

    // A screenshot of the filter study's page (the figures, then the player).
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-page.png");
    let _ = fs::remove_file(&shot);
    browse(
        &filters,
        &[
            format!("--screenshot={}", shot.display()),
            "--window-size=1280,2600".to_string(),
        ],
    );
    let png = fs::read(&shot).expect("a screenshot");
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    assert!(
        png.len() > 50_000,
        "screenshot of {} bytes: blank?",
        png.len()
    );
    eprintln!("screenshot: {}", shot.display());
    assert!(
        t0.elapsed() < Duration::from_secs(60),
        "took {:?}",
        t0.elapsed()
    );
}

/// The opening tag of the element with `id` in `dom`.
fn tag_of<'a>(dom: &'a str, id: &str) -> &'a str {
    let i = dom
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no #{id} in the DOM"));
    let start = dom[..i].rfind('<').unwrap();
    let end = dom[i..].find('>').unwrap() + i;
    &dom[start..=end]
}

/// The player, driven by its self-test (`&selftest` in the link): a link to a moment (the last
/// estimator, the second run, a time half-way) selects that frame, run and estimator; the first
/// and the last frame draw different pictures; Play moves the frames on and a second press
/// pauses; the selectors and the slider answer input events; and the canvas is drawn on.
fn player_plays_scrubs_and_follows_links(page: &Path, frames: &Path) {
    let f: serde_json::Value = serde_json::from_str(&fs::read_to_string(frames).unwrap()).unwrap();
    assert_eq!(f["schema"], "edgekf.frames/1");
    let est = f["estimators"].as_array().unwrap().last().unwrap();
    let label = est["label"].as_str().unwrap();
    let runs = est["runs"].as_array().unwrap();
    assert!(runs.len() >= 2, "two runs recorded ({} here)", runs.len());
    let run = runs[1]["run"].as_u64().unwrap();
    let steps = f["steps"].as_array().unwrap();
    let mid = steps.len() / 2;
    let t = steps[mid].as_f64().unwrap() * f["dt"].as_f64().unwrap();
    let fragment = format!("#t={t}&run={run}&est={label}&selftest");
    let (dom, err) = browse_at(page, &fragment, &["--dump-dom".to_string()]);
    let console: Vec<&str> = err.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(console.is_empty(), "console output {console:?}");
    let player = tag_of(&dom, "player");
    assert_eq!(attr(player, "data-estimator").as_deref(), Some(label));
    assert_eq!(attr(player, "data-run"), Some(run.to_string()));
    let status = tag_of(&dom, "player-status");
    assert_eq!(
        attr(status, "data-hash-frame"),
        Some(mid.to_string()),
        "the link's time selects its frame: {status}"
    );
    assert_eq!(attr(status, "data-frames-differ").as_deref(), Some("true"));
    assert_eq!(attr(status, "data-play-advanced").as_deref(), Some("true"));
    assert_eq!(attr(status, "data-paused").as_deref(), Some("true"));
    assert_eq!(
        attr(status, "data-controls").as_deref(),
        Some("true"),
        "{status}"
    );
    let self_check = tag_of(&dom, "selfcheck");
    assert_eq!(attr(self_check, "data-errors").as_deref(), Some("0"));

    let ink: f64 = attr(status, "data-ink").unwrap().parse().unwrap();
    assert!(ink > 0.005, "the canvas is {ink} drawn: blank?");
}
