//! Links that resolve (issue 33): every relative link and anchor in README.md, PROTOCOL.md and
//! docs/*.md points at a file of the checkout and, for `#anchor`, at a heading GitHub gives that
//! anchor; every guide or section a `--help` text cites exists. The checker is tested on a small
//! set of broken pages first, so a pass below means something.
//!
//! GitHub's anchors: the heading's text as rendered (code spans, emphasis and links reduced to
//! their text), lowercased, every character but letters, digits, spaces, `-` and `_` dropped,
//! spaces turned to `-`; a repeated anchor in one page gets `-1`, `-2`, ... in order.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};
use std::process::Command;

use crate::util::mema_bin;

/// The checkout's root (the tests crate sits in `tests/`).
fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The pages checked, relative to the root: the front door, the protocol and every guide.
fn pages(root: &Path) -> Vec<String> {
    let mut pages = vec!["README.md".to_string(), "PROTOCOL.md".to_string()];
    let mut guides: Vec<String> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    guides.sort();
    pages.extend(guides);
    pages
}

/// The text GitHub renders for a heading's source: code spans, emphasis marks and link targets
/// go, their text stays.
fn rendered(heading: &str) -> String {
    let mut out = String::new();
    let chars: Vec<char> = heading.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        match chars[i] {
            '`' | '*' => i += 1,
            // `[text](target)` keeps `text`; the target is skipped with its parentheses.
            ']' if chars.get(i + 1) == Some(&'(') => {
                i += 2;
                while i < chars.len() && chars[i] != ')' {
                    i += 1;
                }
                i += 1;
            }
            '[' => i += 1,
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    out
}

/// GitHub's anchor for a heading's rendered text.
pub fn slug(text: &str) -> String {
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// A Markdown page's lines outside fenced code blocks, with their 1-based numbers.
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fence: Option<&str> = None;
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let marker = if t.starts_with("```") {
            Some("```")
        } else if t.starts_with("~~~") {
            Some("~~~")
        } else {
            None
        };
        match (fence, marker) {
            (None, Some(m)) => fence = Some(m),
            (Some(f), Some(m)) if f == m => fence = None,
            (None, None) => out.push((n + 1, line)),
            _ => {}
        }
    }
    out
}

/// The anchors a page offers: its headings' (with GitHub's suffixes for repeats) and any HTML
/// `id` or `name` it sets by hand.
pub fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    for (_, line) in prose(text) {
        let t = line.trim_start();
        let hashes = t.chars().take_while(|&c| c == '#').count();
        if (1..=6).contains(&hashes) && t[hashes..].starts_with(' ') {
            let base = slug(&rendered(t[hashes..].trim().trim_end_matches('#')));
            let n = seen.entry(base.clone()).or_insert(0);
            out.insert(if *n == 0 {
                base.clone()
            } else {
                format!("{base}-{n}")
            });
            *n += 1;
        }
        for key in ["id=\"", "name=\""] {
            let mut rest = line;
            while let Some(at) = rest.find(key) {
                rest = &rest[at + key.len()..];
                if let Some(end) = rest.find('"') {
                    out.insert(rest[..end].to_string());
                }
            }
        }
    }
    out
}

/// A line with its code spans blanked, so `[a](b)` shown as code is not taken for a link.
fn without_code_spans(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut in_code = false;
    for c in line.chars() {
        if c == '`' {
            in_code = !in_code;
            out.push(' ');
        } else {
            out.push(if in_code { ' ' } else { c });
        }
    }
    out
}

/// The targets of a page's inline links and images, `[text](target)`, and of its reference
/// definitions, `[label]: target`, with their line numbers.
pub fn link_targets(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (n, line) in prose(text) {
        let line = without_code_spans(line);
        let t = line.trim_start();
        if let Some(close) = t.find("]:").filter(|_| t.starts_with('[')) {
            let target = t[close + 2..].split_whitespace().next().unwrap_or("");
            out.push((n, target.trim_matches(['<', '>']).to_string()));
            continue;
        }
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            // A target ends at its closing parenthesis or at a title (`(target "title")`).
            let end = rest.find([')', ' ']).unwrap_or(rest.len());
            out.push((n, rest[..end].trim_matches(['<', '>']).to_string()));
            rest = &rest[end..];
        }
    }
    out
}

/// `path` with `.` and `..` taken out, or None where it climbs out of the checkout.
fn normalized(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(p) => out.push(p),
            _ => return None,
        }
    }
    Some(out)
}

/// Every broken link of the pages `files` (path relative to the root -> text), as
/// `page:line: target: why`. A page outside `files` is looked up on disk under `root`.
pub fn broken_links(root: &Path, files: &BTreeMap<String, String>) -> Vec<String> {
    let mut broken = Vec::new();
    for (page, text) in files {
        let dir = Path::new(page).parent().unwrap_or(Path::new(""));
        for (line, target) in link_targets(text) {
            if target.is_empty() {
                broken.push(format!("{page}:{line}: an empty link"));
                continue;
            }
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let resolved = if path.is_empty() {
                Some(PathBuf::from(page))
            } else {
                normalized(&dir.join(path))
            };
            let Some(resolved) = resolved else {
                broken.push(format!(
                    "{page}:{line}: {target}: outside the checkout, which a reader of the \
                     repository does not have"
                ));
                continue;
            };
            let key = resolved.to_string_lossy().replace('\\', "/");
            let on_disk = root.join(&resolved);
            let text_there = match files.get(&key) {
                Some(t) => Some(t.clone()),
                None if on_disk.exists() => std::fs::read_to_string(&on_disk).ok(),
                None => {
                    broken.push(format!("{page}:{line}: {target}: no file {key}"));
                    continue;
                }
            };
            let Some(anchor) = anchor else { continue };
            if !key.ends_with(".md") {
                broken.push(format!(
                    "{page}:{line}: {target}: an anchor into {key}, which has no headings"
                ));
                continue;
            }
            let offered = anchors(&text_there.unwrap_or_default());
            if !offered.contains(anchor) {
                broken.push(format!(
                    "{page}:{line}: {target}: {key} has no heading with the anchor #{anchor}"
                ));
            }
        }
    }
    broken
}

/// A `--help` text's citations of the documentation: `README`, `PROTOCOL.md` or
/// `docs/NAME.md`, each optionally narrowed to a section by `#anchor`, `, "Heading"` or
/// ` "Heading"`. Returns (file, section anchor) pairs.
pub fn help_citations(help: &str) -> Vec<(String, Option<String>)> {
    let text = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut out = Vec::new();
    let mut at = 0;
    while at < text.len() {
        let rest = &text[at..];
        let found = ["README", "PROTOCOL.md", "docs/"]
            .iter()
            .filter_map(|k| rest.find(k).map(|i| (i, *k)))
            .min();
        let Some((i, key)) = found else { break };
        let start = at + i;
        let mut end = start + key.len();
        let file = match key {
            "README" => {
                if text[end..].starts_with(".md") {
                    end += 3;
                }
                "README.md".to_string()
            }
            "PROTOCOL.md" => key.to_string(),
            _ => {
                let tail = &text[end..];
                let len = tail
                    .find(|c: char| !(c.is_alphanumeric() || matches!(c, '-' | '_' | '.')))
                    .unwrap_or(tail.len());
                // A sentence's full stop after the name is not part of it.
                let name = tail[..len].trim_end_matches('.');
                end += name.len();
                format!("docs/{name}")
            }
        };
        let tail = &text[end..];
        let section = if let Some(a) = tail.strip_prefix('#') {
            let len = a
                .find(|c: char| !(c.is_alphanumeric() || matches!(c, '-' | '_')))
                .unwrap_or(a.len());
            end += 1 + len;
            Some(a[..len].to_string())
        } else {
            let quoted = tail
                .strip_prefix(", \"")
                .or_else(|| tail.strip_prefix(" \""));
            quoted.and_then(|q| {
                let close = q.find('"')?;
                end += tail.len() - q.len() + close + 1;
                Some(slug(&q[..close]))
            })
        };
        out.push((file, section));
        at = end.max(start + 1);
    }
    out
}

/// Every citation of `help` (from `command`) that names no file of the checkout, or a section
/// that file does not have.
pub fn broken_citations(root: &Path, command: &str, help: &str) -> Vec<String> {
    let mut broken = Vec::new();
    for (file, section) in help_citations(help) {
        let Ok(text) = std::fs::read_to_string(root.join(&file)) else {
            broken.push(format!(
                "`{command} --help` cites {file}, which does not exist"
            ));
            continue;
        };
        match section {
            // The README is the whole front door: "see README" sends the reader nowhere.
            None if file == "README.md" => broken.push(format!(
                "`{command} --help` cites the README without naming its section"
            )),
            None => {}
            Some(section) if !anchors(&text).contains(&section) => broken.push(format!(
                "`{command} --help` cites the section #{section} of {file}, which it \
                     does not have"
            )),
            Some(_) => {}
        }
    }
    broken
}

/// The subcommands a clap `--help` lists under `Commands:` (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in help.lines() {
        if line.starts_with("Commands:") {
            inside = true;
            continue;
        }
        if inside {
            if !line.starts_with("  ") {
                break;
            }
            let indent = line.len() - line.trim_start().len();
            if indent != 2 {
                continue;
            }
            if let Some(name) = line.split_whitespace().next().filter(|&n| n != "help") {
                out.push(name.to_string());
            }
        }
    }
    out
}

fn help_of(args: &[String]) -> String {
    let out = Command::new(mema_bin())
        .args(args)
        .arg("--help")
        .output()
        .expect("run mema --help");
    assert!(
        out.status.success(),
        "mema {} --help failed",
        args.join(" ")
    );
    String::from_utf8(out.stdout).expect("help is UTF-8")
}

#[test]
fn the_checker_finds_each_kind_of_broken_link() {
    let dir = crate::util::Dir::new("links");
    std::fs::create_dir_all(dir.join("docs")).expect("docs/");
    std::fs::write(dir.join("docs/fig.png"), b"png").expect("figure");
    let mut files = BTreeMap::new();
    files.insert(
        "README.md".to_string(),
        "# Top\n\n## The `--units` flag, explained!\n\n## Examples\n\n## Examples\n\n\
         [ok](docs/guide.md) [ok](#the---units-flag-explained) [ok](#examples-1)\n\
         [ok](docs/guide.md#its-part) [ok](https://example.com/x#y)\n\
         `[not a link](nowhere.md)`\n\n```console\n$ echo [not](either.md)\n```\n\
         [bad](docs/missing.md)\n[bad](#examples-2)\n[bad](docs/guide.md#no-such-part)\n\
         [bad](../outside.md)\n[bad]: docs/docs/fig.png\n"
            .to_string(),
    );
    files.insert(
        "docs/guide.md".to_string(),
        "# Guide\n\n## Its part\n\n![ok](fig.png) [ok](../README.md#top)\n\
         [bad](PROTOCOL.md) [bad](#firmware) [ok](#its-part)\n"
            .to_string(),
    );
    let broken = broken_links(&dir.path, &files);
    let lines: Vec<&str> = broken
        .iter()
        .map(|b| b.split(": ").nth(1).unwrap_or(""))
        .collect();
    assert_eq!(
        lines,
        [
            "docs/missing.md",
            "#examples-2",
            "docs/guide.md#no-such-part",
            "../outside.md",
            "docs/docs/fig.png",
            "PROTOCOL.md",
            "#firmware",
        ],
        "{broken:#?}"
    );

    // Citations in a help text: a file alone, a quoted heading, an anchor; and the broken ones.
    std::fs::write(dir.join("README.md"), files["README.md"].as_bytes()).expect("README");
    std::fs::write(dir.join("docs/guide.md"), files["docs/guide.md"].as_bytes()).expect("guide");
    let good = "Move a map (docs/guide.md, \"Its part\"; README \"Examples\"; \
                docs/guide.md#its-part).";
    assert_eq!(
        help_citations(good),
        [
            ("docs/guide.md".to_string(), Some("its-part".to_string())),
            ("README.md".to_string(), Some("examples".to_string())),
            ("docs/guide.md".to_string(), Some("its-part".to_string())),
        ]
    );
    assert!(broken_citations(&dir.path, "mema x", good).is_empty());
    let bad = "Time it (README \"Performance\"). Rotations: see docs/rotations.md, or README.";
    assert_eq!(broken_citations(&dir.path, "mema x", bad).len(), 3, "{bad}");
}

#[test]
fn every_link_and_anchor_of_the_documentation_resolves() {
    let root = repository();
    let files: BTreeMap<String, String> = pages(&root)
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(root.join(&p)).expect("read page");
            (p, text)
        })
        .collect();
    let links: usize = files.values().map(|t| link_targets(t).len()).sum();
    assert!(
        links > 50,
        "only {links} links found: the parser misses them"
    );
    let broken = broken_links(&root, &files);
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn every_section_a_help_text_cites_exists() {
    let root = repository();
    let mut queue = vec![Vec::<String>::new()];
    let mut broken = Vec::new();
    let mut citations = 0;
    let mut commands = 0;
    while let Some(args) = queue.pop() {
        let help = help_of(&args);
        commands += 1;
        let name = format!("mema {}", args.join(" "));
        citations += help_citations(&help).len();
        broken.extend(broken_citations(&root, name.trim_end(), &help));
        for sub in subcommands(&help) {
            let mut next = args.clone();
            next.push(sub);
            queue.push(next);
        }
    }
    assert!(commands > 10, "only {commands} help texts reached");
    assert!(citations > 0, "no help text cites the documentation");
    assert!(
        broken.is_empty(),
        "broken citations:\n{}",
        broken.join("\n")
    );
}
