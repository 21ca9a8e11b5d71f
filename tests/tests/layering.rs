//! The host's layers, checked on its source. The library is everything in `host/src` but the
//! binary's `main.rs` and `cli/`; it must never name clap or the command line, no two of its
//! modules may import each other in a circle, at any level of the module tree (between `io` and
//! `mapping`, say, or between `mapping::pipeline` and `mapping::shells`), and its top-level
//! modules use only the layers below their own ([`LAYERS`]). The command line, a crate of its
//! own, is held to no circle either.
//!
//! References are read from the code, comments and test modules aside: `crate::a::b` paths,
//! `super::`/`self::` paths resolved from the file's module, and `use` trees (`crate::{a, b}`).
//! A path through a re-export (`crate::mapping::Model`) counts as a use of the module that
//! re-exports it, so the library names its sources directly.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One library file: its module path (`["mapping", "pipeline"]`, `[]` for lib.rs) and code.
struct Source {
    file: String,
    module: Vec<String>,
    code: String,
}

/// What the library must not name: the CLI's layer, clap (a derive counts), and the CLI-only
/// crates.
const FORBIDDEN: [&str; 10] = [
    "clap",
    "clap_complete",
    "clap_mangen",
    "ctrlc",
    "crate::cli",
    "super::cli",
    "mod cli",
    "UsageError",
    "ValueEnum",
    "FitArgs",
];

fn host_src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../host/src")
}

/// Code only: `//` comments (doc comments included) are prose, and everything from a file's
/// first `#[cfg(test)]` on is test code (test modules sit at the end, as in `core_contract`).
fn code_of(text: &str) -> String {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    code.lines()
        .map(|line| match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `io/read/mod.rs` is `io::read`, `mapping/pipeline.rs` is `mapping::pipeline`.
fn module_of(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let file = parts.pop().unwrap_or_default();
    let stem = file.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" && stem != "main" {
        parts.push(stem.to_string());
    }
    parts
}

/// The library's files, read from disk; test-only files (`tests.rs`) are left out.
fn library_sources() -> Vec<Source> {
    sources(|relative| relative != Path::new("cli") && relative != Path::new("main.rs"))
}

/// The binary's files: `main.rs` (the crate root) and the command line under `cli/`.
fn cli_sources() -> Vec<Source> {
    sources(|relative| relative == Path::new("main.rs") || relative.starts_with("cli"))
}

/// The files of `host/src` whose path (relative to it) `keep` accepts, a directory's for its
/// whole subtree.
fn sources(keep: impl Fn(&Path) -> bool) -> Vec<Source> {
    let root = host_src();
    let mut out = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("host/src") {
            let path = entry.expect("entry").path();
            let relative = path
                .strip_prefix(&root)
                .expect("under host/src")
                .to_path_buf();
            if relative.components().count() == 1 && !keep(&relative) {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let name = relative.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if !name.ends_with(".rs") || name == "tests.rs" {
                continue;
            }
            let text = std::fs::read_to_string(&path).expect("source");
            out.push(Source {
                file: relative.display().to_string(),
                module: module_of(&relative),
                code: code_of(&text),
            });
        }
    }
    out.sort_by(|a, b| a.file.cmp(&b.file));
    out
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// `what` in `code` standing alone (not inside a longer identifier such as `clamp`).
fn names(code: &str, what: &str) -> bool {
    code.match_indices(what).any(|(i, _)| {
        let before = code[..i].chars().next_back();
        let after = code[i + what.len()..].chars().next();
        !before.is_some_and(is_ident) && !after.is_some_and(is_ident)
    })
}

/// Every forbidden name in the library, as `file: name`.
fn cli_names(sources: &[Source]) -> Vec<String> {
    let mut found = Vec::new();
    for s in sources {
        for f in FORBIDDEN {
            if names(&s.code, f) {
                found.push(format!("{}: {f}", s.file));
            }
        }
    }
    found
}

/// The paths of a `use` tree (or a plain path) starting at `text`, each as its segments; stops
/// at the first character that cannot continue the path.
fn tree_paths(text: &str) -> Vec<Vec<String>> {
    fn parse(text: &[char], at: &mut usize, prefix: &[String], out: &mut Vec<Vec<String>>) {
        let mut path = prefix.to_vec();
        loop {
            while text.get(*at).is_some_and(|c| c.is_whitespace()) {
                *at += 1;
            }
            if text.get(*at) == Some(&'{') {
                *at += 1;
                loop {
                    parse(text, at, &path, out);
                    while text.get(*at).is_some_and(|c| c.is_whitespace()) {
                        *at += 1;
                    }
                    match text.get(*at) {
                        Some(',') => *at += 1,
                        Some('}') => {
                            *at += 1;
                            return;
                        }
                        _ => return,
                    }
                    while text.get(*at).is_some_and(|c| c.is_whitespace()) {
                        *at += 1;
                    }
                    if text.get(*at) == Some(&'}') {
                        *at += 1;
                        return;
                    }
                }
            }
            let start = *at;
            while text.get(*at).copied().is_some_and(is_ident) {
                *at += 1;
            }
            if *at == start {
                break;
            }
            path.push(text[start..*at].iter().collect());
            if text.get(*at) == Some(&':') && text.get(*at + 1) == Some(&':') {
                *at += 2;
            } else {
                break;
            }
        }
        if path.len() > prefix.len() {
            out.push(path);
        }
    }
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    parse(&chars, &mut 0, &[], &mut out);
    out
}

/// The absolute module paths `source` refers to.
fn references(source: &Source) -> Vec<Vec<String>> {
    let code = &source.code;
    let mut out = Vec::new();
    for (i, _) in code.match_indices("::") {
        // The first `::` of a path that starts with `crate`, `self` or a run of `super`s.
        let head_start = code[..i]
            .char_indices()
            .rev()
            .take_while(|(_, c)| is_ident(*c))
            .last()
            .map_or(i, |(j, _)| j);
        let head = &code[head_start..i];
        if code[..head_start].ends_with("::") {
            continue;
        }
        let mut base: Vec<String> = match head {
            "crate" => Vec::new(),
            "self" => source.module.clone(),
            "super" => {
                let mut m = source.module.clone();
                m.pop();
                m
            }
            _ => continue,
        };
        let mut rest = &code[i + 2..];
        if head == "super" {
            while let Some(r) = rest.strip_prefix("super::") {
                base.pop();
                rest = r;
            }
        }
        for tail in tree_paths(rest) {
            let mut path = base.clone();
            path.extend(tail);
            out.push(path);
        }
    }
    out
}

/// Edges between sibling modules: for each module (the root included), which of its children
/// uses which other child, with a file that shows it.
type Siblings = BTreeMap<Vec<String>, BTreeMap<String, BTreeMap<String, String>>>;

fn sibling_edges(sources: &[Source]) -> Siblings {
    let modules: BTreeSet<Vec<String>> = sources.iter().map(|s| s.module.clone()).collect();
    let mut edges = Siblings::new();
    for s in sources {
        for path in references(s) {
            let common = s
                .module
                .iter()
                .zip(&path)
                .take_while(|(a, b)| a == b)
                .count();
            let (Some(from), Some(to)) = (s.module.get(common), path.get(common)) else {
                continue;
            };
            let parent = s.module[..common].to_vec();
            let mut target = parent.clone();
            target.push(to.clone());
            // Items of the parent (`super::Cloud`) are not sibling modules.
            if !modules.contains(&target) {
                continue;
            }
            edges
                .entry(parent)
                .or_default()
                .entry(from.clone())
                .or_default()
                .entry(to.clone())
                .or_insert_with(|| s.file.clone());
        }
    }
    edges
}

/// Each circle among siblings, as `parent: a -> b -> a (a: file, b: file)`.
fn cycles(edges: &Siblings) -> Vec<String> {
    let mut found = Vec::new();
    for (parent, graph) in edges {
        let mut done = BTreeSet::new();
        for start in graph.keys() {
            let mut stack = vec![start.clone()];
            visit(graph, &mut stack, &mut done, &mut |cycle| {
                let shown: Vec<String> = cycle
                    .windows(2)
                    .map(|w| format!("{} uses {} in {}", w[0], w[1], graph[&w[0]][&w[1]]))
                    .collect();
                let name = if parent.is_empty() {
                    "crate".to_string()
                } else {
                    parent.join("::")
                };
                found.push(format!(
                    "{name}: {} ({})",
                    cycle.join(" -> "),
                    shown.join("; ")
                ));
            });
        }
    }
    found
}

fn visit(
    graph: &BTreeMap<String, BTreeMap<String, String>>,
    stack: &mut Vec<String>,
    done: &mut BTreeSet<String>,
    report: &mut dyn FnMut(Vec<String>),
) {
    let Some(node) = stack.last().cloned() else {
        return;
    };
    if done.contains(&node) {
        return;
    }
    for next in graph.get(&node).into_iter().flat_map(|e| e.keys()) {
        if let Some(at) = stack.iter().position(|m| m == next) {
            let mut cycle = stack[at..].to_vec();
            cycle.push(next.clone());
            report(cycle);
        } else {
            stack.push(next.clone());
            visit(graph, stack, done, report);
            stack.pop();
        }
    }
    done.insert(node);
}

#[test]
fn the_library_names_no_command_line() {
    let sources = library_sources();
    assert!(sources.len() >= 40, "only {} library files", sources.len());
    let found = cli_names(&sources);
    assert!(
        found.is_empty(),
        "the library names the command line:\n{}",
        found.join("\n")
    );
    let main = std::fs::read_to_string(host_src().join("main.rs")).expect("main.rs");
    assert!(main.contains("mod cli;"), "main.rs owns the command line");
    assert!(host_src().join("cli").is_dir());
    // An embedder leaves the command line's crates out with `default-features = false`
    // (scripts/test.sh builds the library so).
    let manifest =
        std::fs::read_to_string(host_src().join("../Cargo.toml")).expect("host/Cargo.toml");
    for dep in ["clap", "clap_complete", "clap_mangen", "ctrlc"] {
        let line = manifest
            .lines()
            .find(|l| l.starts_with(&format!("{dep} =")))
            .unwrap_or_else(|| panic!("{dep} in host/Cargo.toml"));
        assert!(
            line.contains("optional = true"),
            "{dep} is the cli feature's: {line}"
        );
    }
}

/// Whether an input is a registration file, a bag or a cloud is decided in one place,
/// `io::kind::InputKind::of` (it was decided in io/cloud.rs, link/scanner.rs and three
/// commands, each asking the predicates again); everything else asks it.
#[test]
fn one_place_decides_what_an_input_is() {
    let sources: Vec<Source> = sources(|_| true);
    let deciders: Vec<String> = sources
        .iter()
        .filter(|s| names(&s.code, "is_bag") || names(&s.code, "is_registration"))
        .filter(|s| !s.code.contains("fn is_bag") && !s.code.contains("fn is_registration"))
        .map(|s| s.file.clone())
        .collect();
    assert_eq!(
        deciders,
        ["io/kind.rs"],
        "asking what an input is outside io/kind.rs"
    );
    let askers = sources
        .iter()
        .filter(|s| names(&s.code, "InputKind"))
        .count();
    assert!(askers >= 4, "InputKind asked in {askers} files");
}

#[test]
fn no_two_library_modules_import_each_other_in_a_circle() {
    let sources = library_sources();
    let edges = sibling_edges(&sources);
    // The layers themselves are seen, so a circle could be.
    let root = edges
        .get(&Vec::new())
        .expect("edges between top-level modules");
    assert!(
        root.get("batch")
            .is_some_and(|to| to.contains_key("mapping"))
    );
    assert!(root.get("analysis").is_some_and(|to| to.contains_key("io")));
    let found = cycles(&edges);
    assert!(
        found.is_empty(),
        "modules import each other in a circle:\n{}",
        found.join("\n")
    );
    // The binary is a crate of its own (`crate::` is main.rs there): its command line too.
    let cli = cli_sources();
    assert!(cli.len() >= 10, "only {} command-line files", cli.len());
    let found = cycles(&sibling_edges(&cli));
    assert!(
        found.is_empty(),
        "command-line modules import each other in a circle:\n{}",
        found.join("\n")
    );
}

/// The top-level modules from the bottom layer up, as the crate documentation and the README
/// list them: each uses only modules of the layers below its own.
const LAYERS: [&[&str]; 7] = [
    &["error", "progress", "heap", "kdtree"],
    &["io"],
    &["mapping"],
    &["analysis"],
    &["batch"],
    &["render", "query", "link"],
    &["bench"],
];

/// Edges of the root module that do not go down the layers, or reach a module not in them.
fn against_the_layers(edges: &Siblings, modules: &BTreeSet<String>) -> Vec<String> {
    let rank = |m: &str| LAYERS.iter().position(|layer| layer.contains(&m));
    let mut found: Vec<String> = modules
        .iter()
        .filter(|m| rank(m).is_none())
        .map(|m| format!("{m} is in no layer"))
        .collect();
    for (from, to) in edges.get(&Vec::new()).into_iter().flatten() {
        for (to, file) in to {
            if let (Some(a), Some(b)) = (rank(from), rank(to))
                && b >= a
            {
                found.push(format!(
                    "{from} uses {to} (in {file}), a layer not below its own"
                ));
            }
        }
    }
    found
}

#[test]
fn the_top_level_modules_use_only_the_layers_below() {
    let sources = library_sources();
    let modules: BTreeSet<String> = sources
        .iter()
        .filter_map(|s| s.module.first().cloned())
        .collect();
    let found = against_the_layers(&sibling_edges(&sources), &modules);
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// The checks on planted violations: each must be caught.
#[test]
fn the_checks_catch_planted_violations() {
    let source = |file: &str, text: &str| Source {
        file: file.into(),
        module: module_of(Path::new(file)),
        code: code_of(text),
    };
    let clean = [
        source(
            "io/mapfile.rs",
            "// crate::cli is named in a comment only\nuse std::path::Path;\nfn clamp() {}",
        ),
        source("io/mod.rs", "pub mod mapfile;"),
    ];
    assert!(cli_names(&clean).is_empty());
    for bad in [
        "use crate::cli::UsageError;",
        "#[derive(Clone, clap::ValueEnum)]\nenum View { Iso }",
        "fn f() -> Result<(), UsageError> { todo!() }",
    ] {
        assert!(
            !cli_names(&[source("io/mapfile.rs", bad)]).is_empty(),
            "{bad}"
        );
    }

    // Top level: io uses render, render uses io through a use tree.
    let circle = [
        source("io/mapfile.rs", "fn f() { crate::render::draw::x(); }"),
        source(
            "render/draw.rs",
            "use crate::{io::mapfile::HostMap, error};",
        ),
        source("render/mod.rs", "pub mod draw;"),
        source("io/mod.rs", "pub mod mapfile;"),
        source("error.rs", ""),
    ];
    let found = cycles(&sibling_edges(&circle));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with("crate: io -> render -> io"),
        "{found:?}"
    );

    // Siblings: shells uses pipeline through super::, pipeline uses shells by crate path.
    let siblings = [
        source("mapping/shells.rs", "use super::pipeline::Members;"),
        source(
            "mapping/pipeline.rs",
            "const N: usize = crate::mapping::shells::BYTES;",
        ),
        source("mapping/filter.rs", "use super::super::io::read;"),
        source("mapping/mod.rs", "pub mod shells;\npub mod pipeline;"),
    ];
    let found = cycles(&sibling_edges(&siblings));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("mapping: pipeline -> shells -> pipeline"));

    // A parent's own items, and test code, make no edge.
    let fine = [
        source("io/read/xyz.rs", "use super::{Cloud, stream::Input};"),
        source(
            "io/read/stream.rs",
            "#[cfg(test)]\nmod tests { use super::super::xyz::f; }",
        ),
        source("io/read/mod.rs", "pub struct Cloud;"),
    ];
    assert!(cycles(&sibling_edges(&fine)).is_empty());
}
