//! Every relative link of the project's Markdown resolves: the README, ARCHITECTURE.md, `docs/`
//! (the user guide's sources, `docs/book/src/`, among them), and the crates' READMEs. mdBook has
//! no link checker, so this is it (std only, no network: `http(s)` links are not checked).
//!
//! A link's file must exist and, for `#anchor` links into Markdown, the heading must exist.
//! Files outside the guide are read as GitHub shows them (its heading slugs, the file as
//! written). The guide's chapters are read as mdBook renders them: `{{#include …}}` expanded
//! (with `:anchor` and line ranges), mdBook's heading ids, and every link must stay inside
//! `docs/book/src/` — mdBook copies nothing else into the book, and rewrites a link to any
//! `.md` file into `.html`. Every chapter must be listed in `SUMMARY.md`.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Component, Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The repository's Markdown files, skipping build outputs and hidden directories.
fn markdown_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with('.')
            // Build outputs, and the outputs the README's commands write.
            || ["target", "node_modules", "__pycache__", "venv", "figures", "out"]
                .contains(&name.as_str())
        {
            continue;
        }
        if p.is_dir() {
            markdown_files(&p, out);
        } else if name.ends_with(".md") {
            out.push(p);
        }
    }
}

/// `a/./b/../c` → `a/c`, without touching the file system.
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// `%20` and friends decoded (links may percent-encode spaces and Unicode).
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).unwrap_or("");
            if let Ok(v) = u8::from_str_radix(hex, 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The text with mdBook's `{{#include path}}` (also `:anchor`, `:from:to` line ranges, and
/// `{{#rustdoc_include …}}`) expanded, recursively, paths relative to `file`.
fn expand_includes(file: &Path, text: &str, depth: usize) -> Result<String, String> {
    if depth > 10 {
        return Err(format!("{}: includes nested too deeply", file.display()));
    }
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find("{{#") {
        let escaped = rest[..at].ends_with('\\');
        out.push_str(&rest[..at]);
        let Some(len) = rest[at..].find("}}") else {
            out.push_str(&rest[at..]);
            return Ok(out);
        };
        let directive = &rest[at + 3..at + len];
        rest = &rest[at + len + 2..];
        let (name, arg) = directive
            .trim()
            .split_once(char::is_whitespace)
            .unwrap_or((directive, ""));
        if escaped || !matches!(name, "include" | "rustdoc_include") {
            out.push_str("{{#");
            out.push_str(directive);
            out.push_str("}}");
            continue;
        }
        let arg = arg.trim();
        let (path, selector) = arg.split_once(':').unwrap_or((arg, ""));
        let target = normalise(&file.parent().unwrap().join(path));
        let body = fs::read_to_string(&target).map_err(|e| {
            format!(
                "{}: `{{{{#{directive}}}}}`: {}: {e}",
                file.display(),
                target.display()
            )
        })?;
        let body = select(&body, selector).ok_or_else(|| {
            format!(
                "{}: `{{{{#{directive}}}}}`: no `{selector}` in {}",
                file.display(),
                target.display()
            )
        })?;
        out.push_str(&expand_includes(&target, &body, depth + 1)?);
    }
    out.push_str(rest);
    Ok(out)
}

/// The part of an included file that `selector` names (mdBook's rules): everything (empty),
/// the lines between `ANCHOR: name` and `ANCHOR_END: name` (without any anchor lines), or a
/// 1-based inclusive line range `from`, `from:to`, `:to`, `from:`.
fn select(body: &str, selector: &str) -> Option<String> {
    if selector.is_empty() {
        return Some(body.to_string());
    }
    let is_marker = |l: &str| l.contains("ANCHOR:") || l.contains("ANCHOR_END:");
    let names = |l: &str, key: &str| -> Option<String> {
        let at = l.find(key)? + key.len();
        let name: String = l[at..]
            .trim_start()
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == '-')
            .collect();
        Some(name)
    };
    if selector
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_digit() || c == ':')
    {
        let lines: Vec<&str> = body.lines().collect();
        let (from, to) = selector.split_once(':').unwrap_or((selector, selector));
        let from = if from.is_empty() {
            1
        } else {
            from.parse().ok()?
        };
        let to = if to.is_empty() {
            lines.len()
        } else {
            to.parse().ok()?
        };
        let from = usize::max(from, 1);
        return Some(lines.get(from - 1..to.min(lines.len()))?.join("\n"));
    }
    let mut inside = false;
    let mut found = false;
    let mut out = Vec::new();
    for l in body.lines() {
        if names(l, "ANCHOR_END:").as_deref() == Some(selector) && inside {
            return found.then(|| out.join("\n"));
        }
        if !inside && names(l, "ANCHOR:").as_deref() == Some(selector) {
            inside = true;
            found = true;
            continue;
        }
        if inside && !is_marker(l) {
            out.push(l);
        }
    }
    None
}

/// The text with fenced code blocks and HTML comments blanked (line breaks kept, so offsets
/// still give line numbers).
fn prose(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut fence: Option<String> = None;
    for l in text.split_inclusive('\n') {
        let t = l.trim_start();
        let marker: String = t.chars().take_while(|&c| c == '`' || c == '~').collect();
        let is_fence =
            marker.len() >= 3 && marker.chars().all(|c| c == marker.chars().next().unwrap());
        match &fence {
            None if is_fence => {
                fence = Some(marker);
                out.push('\n');
            }
            Some(open) => {
                if is_fence
                    && marker.starts_with(open.as_str())
                    && t[marker.len()..].trim().is_empty()
                {
                    fence = None;
                }
                out.push('\n');
            }
            None => out.push_str(l),
        }
    }
    // HTML comments.
    let mut s = String::with_capacity(out.len());
    let mut rest = out.as_str();
    while let Some(a) = rest.find("<!--") {
        s.push_str(&rest[..a]);
        let end = rest[a..].find("-->").map_or(rest.len(), |e| a + e + 3);
        s.extend(rest[a..end].chars().filter(|&c| c == '\n'));
        rest = &rest[end..];
    }
    s.push_str(rest);
    s
}

/// The text with the contents of code spans blanked (a run of n backticks to the next run of n,
/// within a paragraph).
fn without_code_spans(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for para in text.split_inclusive("\n\n") {
        let chars: Vec<char> = para.chars().collect();
        let mut i = 0;
        while i < chars.len() {
            if chars[i] != '`' {
                out.push(chars[i]);
                i += 1;
                continue;
            }
            let n = chars[i..].iter().take_while(|&&c| c == '`').count();
            // The closing run of exactly n backticks.
            let mut j = i + n;
            let mut close = None;
            while j < chars.len() {
                if chars[j] == '`' {
                    let m = chars[j..].iter().take_while(|&&c| c == '`').count();
                    if m == n {
                        close = Some(j);
                        break;
                    }
                    j += m;
                } else {
                    j += 1;
                }
            }
            match close {
                Some(j) => {
                    out.extend(
                        chars[i..j + n]
                            .iter()
                            .map(|&c| if c == '\n' { '\n' } else { ' ' }),
                    );
                    i = j + n;
                }
                None => {
                    out.extend(&chars[i..i + n]);
                    i += n;
                }
            }
        }
    }
    out
}

/// Every link target of `text` with its line (1-based): inline links and images `](target)`,
/// reference definitions `[name]: target`, and HTML `href="…"` / `src="…"`.
fn links(text: &str) -> Vec<(usize, String)> {
    let text = without_code_spans(&prose(text));
    let line_of = |at: usize| text[..at].matches('\n').count() + 1;
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(p) = text[from..].find("](") {
        let start = from + p + 2;
        let mut depth = 1;
        let mut end = None;
        for (k, c) in text[start..].char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        end = Some(start + k);
                        break;
                    }
                }
                _ => {}
            }
        }
        from = start;
        let Some(end) = end else { continue };
        let inner = text[start..end].trim();
        let target = if let Some(t) = inner.strip_prefix('<') {
            t.split('>').next().unwrap_or("")
        } else {
            inner.split_whitespace().next().unwrap_or("")
        };
        out.push((line_of(start), target.to_string()));
    }
    for (n, l) in text.lines().enumerate() {
        let t = l.trim_start();
        if l.len() - t.len() <= 3 && t.starts_with('[') && !t.starts_with("[^") {
            if let Some(close) = t.find("]:") {
                let target = t[close + 2..].split_whitespace().next().unwrap_or("");
                out.push((n + 1, target.trim_matches(['<', '>']).to_string()));
            }
        }
        for key in ["href=\"", "src=\""] {
            let mut rest = l;
            while let Some(a) = rest.find(key) {
                let v = &rest[a + key.len()..];
                let v = &v[..v.find('"').unwrap_or(v.len())];
                out.push((n + 1, v.to_string()));
                rest = &rest[a + key.len()..];
            }
        }
    }
    out
}

/// How a heading's text becomes its id.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Slugs {
    /// GitHub: lowercase; letters, digits, combining marks, `_`, `-` kept; a space becomes `-`;
    /// the rest dropped.
    GitHub,
    /// mdBook 0.4: ASCII lowercase; alphanumerics, `_`, `-` kept; whitespace becomes `-`.
    MdBook,
}

fn slug(text: &str, rule: Slugs) -> String {
    let mut out = String::new();
    // Combining diacritical marks (the hat of x̂): GitHub keeps them, mdBook does not.
    let mark = |c: char| matches!(c, '\u{300}'..='\u{36f}' | '\u{20d0}'..='\u{20ff}');
    for c in text.trim().chars() {
        if rule == Slugs::GitHub && mark(c) {
            out.push(c);
        } else if c.is_alphanumeric() || c == '_' || c == '-' {
            match rule {
                Slugs::GitHub => out.extend(c.to_lowercase()),
                Slugs::MdBook => out.push(c.to_ascii_lowercase()),
            }
        } else if (rule == Slugs::GitHub && c == ' ')
            || (rule == Slugs::MdBook && c.is_whitespace())
        {
            out.push('-');
        }
    }
    out
}

/// The visible text of a heading's Markdown: code spans, links and emphasis reduced to their
/// text, HTML tags dropped.
fn heading_text(md: &str) -> String {
    let mut s = md.replace('`', "");
    // [text](url) → text, ![alt](url) → alt.
    while let Some(a) = s.find("](") {
        let Some(open) = s[..a].rfind('[') else { break };
        let Some(close) = s[a..].find(')') else { break };
        let text = s[open + 1..a].to_string();
        let bang = usize::from(open > 0 && s.as_bytes()[open - 1] == b'!');
        s.replace_range(open - bang..a + close + 1, &text);
    }
    let mut out = String::new();
    let mut in_tag = false;
    for c in s.chars() {
        match c {
            '<' => in_tag = true,
            '>' if in_tag => in_tag = false,
            '*' => {}
            c if !in_tag => out.push(c),
            _ => {}
        }
    }
    out
}

/// The ids a Markdown text's headings get (and explicit `id="…"` / `name="…"` anchors).
fn anchors(text: &str, rule: Slugs) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for l in prose(text).lines() {
        let t = l.trim_start();
        let level = t.chars().take_while(|&c| c == '#').count();
        if l.len() - t.len() > 3 || !(1..=6).contains(&level) {
            continue;
        }
        let rest = &t[level..];
        if !(rest.is_empty() || rest.starts_with(' ') || rest.starts_with('\t')) {
            continue;
        }
        let mut h = rest.trim().trim_end_matches('#').trim_end().to_string();
        // mdBook's explicit ids: `# Heading {#id}`.
        if rule == Slugs::MdBook && h.ends_with('}') {
            if let Some(a) = h.rfind("{#") {
                out.insert(h[a + 2..h.len() - 1].to_string());
                continue;
            }
        }
        h = heading_text(&h);
        let base = slug(&h, rule);
        let mut id = base.clone();
        let mut n = 1;
        while out.contains(&id) {
            id = format!("{base}-{n}");
            n += 1;
        }
        out.insert(id);
    }
    for key in ["id=\"", "name=\""] {
        let mut rest = text;
        while let Some(a) = rest.find(key) {
            let v = &rest[a + key.len()..];
            out.insert(v[..v.find('"').unwrap_or(v.len())].to_string());
            rest = &rest[a + key.len()..];
        }
    }
    out
}

/// The broken links of `files` (paths under `root`), one line each; `book` is the guide's
/// source directory (its chapters are read as mdBook renders them).
fn broken_links(root: &Path, files: &[PathBuf], book: &Path) -> Vec<String> {
    let mut broken = Vec::new();
    let rel = |p: &Path| p.strip_prefix(root).unwrap_or(p).display().to_string();
    for file in files {
        let raw = fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let in_book = file.starts_with(book);
        let text = if in_book {
            match expand_includes(file, &raw, 0) {
                Ok(t) => t,
                Err(e) => {
                    broken.push(e);
                    continue;
                }
            }
        } else {
            raw.clone()
        };
        let rule = if in_book {
            Slugs::MdBook
        } else {
            Slugs::GitHub
        };
        let expanded = if in_book && text != raw {
            " (with its includes)"
        } else {
            ""
        };
        for (line, target) in links(&text) {
            let at = format!("{}{expanded}:{line}: `{target}`", rel(file));
            if target.is_empty() {
                broken.push(format!("{at}: empty link"));
                continue;
            }
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, fragment) = target.split_once('#').unwrap_or((&target, ""));
            let path = percent_decode(path);
            if path.starts_with('/') {
                broken.push(format!("{at}: an absolute path (use a relative one)"));
                continue;
            }
            let dest = if path.is_empty() {
                file.clone()
            } else {
                normalise(&file.parent().unwrap().join(&path))
            };
            if !dest.exists() {
                broken.push(format!("{at}: no such file {}", rel(&dest)));
                continue;
            }
            if in_book && !dest.starts_with(book) {
                broken.push(format!(
                    "{at}: leaves the guide ({}): mdBook copies only docs/book/src into the book",
                    rel(&dest)
                ));
                continue;
            }
            if in_book && dest.is_dir() {
                broken.push(format!("{at}: a directory, which the book does not have"));
                continue;
            }
            if fragment.is_empty() || dest.extension().is_none_or(|x| x != "md") {
                continue;
            }
            let dest_text = fs::read_to_string(&dest).unwrap_or_default();
            let dest_text = if in_book {
                expand_includes(&dest, &dest_text, 0).unwrap_or(dest_text)
            } else {
                dest_text
            };
            let fragment = percent_decode(fragment);
            if !anchors(&dest_text, rule).contains(&fragment) {
                broken.push(format!("{at}: no heading `#{fragment}` in {}", rel(&dest)));
            }
        }
    }
    broken
}

/// The chapters of the guide that `SUMMARY.md` does not list.
fn unlisted_chapters(book: &Path) -> Vec<String> {
    let summary = fs::read_to_string(book.join("SUMMARY.md")).expect("docs/book/src/SUMMARY.md");
    let listed: BTreeSet<PathBuf> = links(&summary)
        .into_iter()
        .map(|(_, t)| normalise(&book.join(t.split('#').next().unwrap())))
        .collect();
    let mut chapters = Vec::new();
    markdown_files(book, &mut chapters);
    chapters
        .into_iter()
        .filter(|c| {
            c.file_name().is_some_and(|n| n != "SUMMARY.md") && !listed.contains(&normalise(c))
        })
        .map(|c| c.display().to_string())
        .collect()
}

#[test]
fn every_relative_link_of_the_docs_resolves() {
    let root = normalise(&root());
    let book = root.join("docs/book/src");
    let mut files = Vec::new();
    markdown_files(&root, &mut files);
    for want in [
        "README.md",
        "ARCHITECTURE.md",
        "docs/formats.md",
        "docs/book/src/SUMMARY.md",
    ] {
        assert!(files.contains(&root.join(want)), "{want} is checked");
    }
    let broken = broken_links(&root, &files, &book);
    assert!(
        broken.is_empty(),
        "{} broken link(s):\n{}",
        broken.len(),
        broken.join("\n")
    );
    let unlisted = unlisted_chapters(&book);
    assert!(
        unlisted.is_empty(),
        "chapters missing from SUMMARY.md: {unlisted:?}"
    );
}

/// The checker itself finds what it must (a checker that passes everything checks nothing).
#[test]
fn the_checker_reports_broken_links() {
    let dir = std::env::temp_dir().join(format!("edgekf-docs-links-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    let book = dir.join("docs/book/src");
    fs::create_dir_all(book.join("img")).unwrap();
    fs::write(
        dir.join("notes.md"),
        "# Notes & more\n\n## `x̂` at k\n\n\
         <!-- ANCHOR: part -->\nsee [a](#nowhere)\n<!-- ANCHOR_END: part -->\n",
    )
    .unwrap();
    fs::write(
        dir.join("README.md"),
        "# Top\n\n[ok](notes.md#notes--more) [ok](notes.md#x̂-at-k) [ok](#top) \
         [web](https://example.org/x) `[code](missing.md)`\n\n\
         [gone](missing.md) [bad anchor](notes.md#nope)\n\n```\n[fenced](missing.md)\n```\n\n\
         [split\nacross](docs/book/src/a.md)\n",
    )
    .unwrap();
    fs::write(book.join("img/p.png"), b"").unwrap();
    fs::write(book.join("SUMMARY.md"), "# Summary\n\n- [A](a.md)\n").unwrap();
    fs::write(
        book.join("a.md"),
        "# A & B\n\n![p](img/p.png) [self](#a--b) [in](#part-heading)\n\n\
         {{#include ../../../notes.md:part}}\n\n[out](../../../notes.md) [html](a.md#nope)\n\n\
         ## Part heading\n",
    )
    .unwrap();
    fs::write(book.join("orphan.md"), "# Orphan\n").unwrap();
    let files = vec![
        dir.join("README.md"),
        dir.join("notes.md"),
        book.join("a.md"),
    ];
    let broken = broken_links(&dir, &files, &book);
    let has = |what: &str| broken.iter().any(|b| b.contains(what));
    assert!(has("README.md:5: `missing.md`: no such file"), "{broken:?}");
    assert!(
        has("README.md:5: `notes.md#nope`: no heading"),
        "{broken:?}"
    );
    assert!(
        has("`#nowhere`: no heading"),
        "the included anchor's link, and notes.md's own: {broken:?}"
    );
    assert!(has("`../../../notes.md`: leaves the guide"), "{broken:?}");
    assert!(has("`a.md#nope`: no heading"), "{broken:?}");
    // What must pass: anchors with `&` and Unicode, a link split over lines, images, web links,
    // code spans and fences, the included part's own text.
    assert_eq!(broken.len(), 6, "{broken:?}");
    assert_eq!(
        unlisted_chapters(&book),
        vec![book.join("orphan.md").display().to_string()]
    );
    // A missing include anchor is an error, not an empty include.
    fs::write(book.join("a.md"), "{{#include ../../../notes.md:absent}}\n").unwrap();
    let broken = broken_links(&dir, &[book.join("a.md")], &book);
    assert!(
        broken.len() == 1 && broken[0].contains("no `absent`"),
        "{broken:?}"
    );
    let _ = fs::remove_dir_all(&dir);
}
