//! The guides as the tests that hold their figures read them (issue 32): README.md, PROTOCOL.md
//! and docs/*.md, the result blocks `scripts/results.sh` writes into docs/results.md and the
//! guides copy, and `says`, which holds a guide to a sentence a test makes from what it computed.
//! `scripts/doc_digits.py` reads the `says(FILE, ...)` calls and the templates of quoted.rs and
//! doc_constants.rs to tell which of a guide's numbers a test holds; keep the file a literal and
//! the sentence a literal or a `format!` literal so that it can.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

pub const RESULTS: &str = "docs/results.md";

/// A `<!-- result NAME -->` block: its name, the line it starts on, and its body.
pub struct Block {
    pub name: String,
    pub line: usize,
    pub body: String,
}

/// The result blocks of a text. A block indented in a list item has its lines indented alike;
/// the body is given without that indentation.
pub fn blocks(text: &str, file: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((n, line)) = lines.next() {
        let Some(name) = line
            .trim()
            .strip_prefix("<!-- result ")
            .and_then(|l| l.strip_suffix("-->"))
        else {
            continue;
        };
        let indent = &line[..line.len() - line.trim_start().len()];
        let mut body = Vec::new();
        let mut closed = false;
        for (_, inner) in lines.by_ref() {
            if inner.trim() == "<!-- /result -->" {
                closed = true;
                break;
            }
            body.push(inner.strip_prefix(indent).unwrap_or(inner));
        }
        assert!(closed, "{file}:{}: a result block never closed", n + 1);
        out.push(Block {
            name: name.trim().to_string(),
            line: n + 1,
            body: body.join("\n"),
        });
    }
    out
}

/// docs/results.md's blocks, by name.
pub fn results() -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(repository().join(RESULTS)).expect("docs/results.md");
    let mut map = BTreeMap::new();
    for block in blocks(&text, RESULTS) {
        let (name, line) = (block.name.clone(), block.line);
        assert!(
            map.insert(block.name, block.body).is_none(),
            "{RESULTS}:{line}: a second block `{name}`"
        );
    }
    map
}

/// The body of docs/results.md's block `name`.
pub fn result_block(name: &str) -> String {
    results()
        .remove(name)
        .unwrap_or_else(|| panic!("{RESULTS}: no block `{name}`"))
}

/// Set by scripts/results.sh while it runs the tests that print a block (tests/tests/pacing.rs):
/// they print it instead of holding it to docs/results.md.
pub fn regenerating() -> bool {
    std::env::var_os("MEMA_RESULTS_REGENERATING").is_some()
}

/// The cells of a block's table rows (header and rule aside), backticks trimmed.
pub fn table_rows(block: &str) -> Vec<Vec<String>> {
    block
        .lines()
        .filter(|l| l.starts_with('|'))
        .skip(2)
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().trim_matches('`').to_string())
                .collect()
        })
        .collect()
}

/// README.md, PROTOCOL.md and the guides, the results file aside.
pub fn documents() -> Vec<(String, String)> {
    let root = repository();
    let mut files = vec!["README.md".to_string(), "PROTOCOL.md".to_string()];
    let mut guides: Vec<String> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".md") && format!("docs/{f}") != RESULTS)
        .map(|f| format!("docs/{f}"))
        .collect();
    guides.sort();
    files.extend(guides);
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(root.join(&f)).expect("document");
            (f, text)
        })
        .collect()
}

/// A small count as the guides write it: a word up to three.
pub fn word(n: usize) -> String {
    match n {
        1 => "one".into(),
        2 => "two".into(),
        3 => "three".into(),
        n => n.to_string(),
    }
}

/// A figure as the script prints it: thousands separated by commas.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Every run of white space one space: a sentence held in a guide does not care where the guide
/// breaks its lines.
pub fn one_space(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A template with every `{placeholder}` replaced by `value(placeholder)`.
pub fn expand(template: &str, mut value: impl FnMut(&str) -> String) -> String {
    let mut out = String::new();
    let mut rest = template;
    while let Some(start) = rest.find('{') {
        out.push_str(&rest[..start]);
        let end = rest[start..].find('}').expect("a closing brace") + start;
        out.push_str(&value(&rest[start + 1..end]));
        rest = &rest[end + 1..];
    }
    out.push_str(rest);
    out
}

/// Holds every `(guide, template)` to the guide: it must say what the template makes.
pub fn each_says(templates: &[(&str, &str)], mut value: impl FnMut(&str) -> String, whence: &str) {
    let documents: BTreeMap<String, String> = documents()
        .into_iter()
        .map(|(f, t)| (f, one_space(&t)))
        .collect();
    for (file, template) in templates {
        let text = documents
            .get(*file)
            .unwrap_or_else(|| panic!("no guide {file}"));
        let quote = one_space(&expand(template, &mut value));
        assert!(
            text.contains(&quote),
            "{file} does not say `{quote}` ({whence}: `{template}`)"
        );
    }
}

/// Holds a guide to a sentence a test made from what it computed: a figure changed in the guide,
/// or a change in what the test computes, fails until the two agree again.
pub fn says(file: &str, sentence: &str) {
    let text = std::fs::read_to_string(repository().join(file)).expect("guide");
    assert!(
        one_space(&text).contains(&one_space(sentence)),
        "{file} does not say `{sentence}`, which the test computes"
    );
}

/// The default `mema command --help` gives `flag`, as the guides write it (a count with its
/// thousands separated).
pub fn cli_default(command: &str, flag: &str) -> String {
    let out = std::process::Command::new(crate::util::mema_bin())
        .args([command, "--help"])
        .output()
        .expect("mema runs");
    let help = String::from_utf8(out.stdout).expect("text");
    let at = help
        .lines()
        .position(|l| l.trim_start().starts_with(flag) || l.contains(&format!(", {flag} ")))
        .unwrap_or_else(|| panic!("`mema {command} --help` has no {flag}"));
    let rest: String = help.lines().skip(at).collect::<Vec<_>>().join("\n");
    let value = rest
        .split("[default: ")
        .nth(1)
        .and_then(|v| v.split(']').next())
        .unwrap_or_else(|| panic!("`mema {command} --help`: no default for {flag}"));
    match value.parse::<u64>() {
        Ok(n) => thousands(n),
        Err(_) => value.to_string(),
    }
}

#[test]
fn thousands_are_separated_as_the_script_separates_them() {
    assert_eq!(thousands(0), "0");
    assert_eq!(thousands(999), "999");
    assert_eq!(thousands(1_000), "1,000");
    assert_eq!(thousands(239_064), "239,064");
    assert_eq!(thousands(1_320_000), "1,320,000");
}

#[test]
fn a_template_expands_each_placeholder() {
    let value = |p: &str| p.to_uppercase();
    assert_eq!(expand("a {b} c {d}", value), "a B c D");
    assert_eq!(expand("none", value), "none");
}
