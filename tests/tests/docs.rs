//! The documentation's commands, run as written (issue 24): every ```console block of README.md,
//! PROTOCOL.md and docs/*.md. A `$ ` line is a command (a trailing `\` continues it), an optional
//! `? N` line under it the exit status it documents (0 when absent), and the lines after it the
//! output it documents, stdout and stderr together as a terminal shows them. In that output a
//! line `...` stands for any number of lines and `[..]` for any text within a line (the
//! conventions of trycmd and snapbox), kept for what truly varies: times, rates, paths, the
//! lines of a long report around the ones that matter. A command shown without output must
//! print nothing (`cmp`, a command whose output goes to a file); a command whose output is
//! shown as `...` alone would be held to its exit status only, and
//! `no_command_is_held_to_its_exit_status_alone` refuses it. A file with no command is not
//! tested, and says so: it is in `NO_COMMANDS`, not in the tests below. Commands belong in console blocks: a ```sh, ```bash or ```shell block is
//! refused, so a command cannot be shown untested.
//!
//! Each file runs in a fresh scratch checkout (`target/docs-run/<file>/checkout`): symlinks to
//! the repository's top-level entries and `../shared`, so commands run from the root as a user's
//! would, while the files they write stay out of the repository. The commands run in order,
//! each in `bash` in its own process group (killed when the file is done, so a server started
//! with `&` cannot outlive it), with `target/release` and the Python environment
//! (`target/py-venv`, made by scripts/test.sh) first on the PATH, and cargo's builds in
//! `target/docs-cargo`, so `cargo install` and `pip install` never rebuild under the other tests.
//! Two commands are not run: `scripts/test.sh`, which is what runs this, and the benchmark
//! commands whose full runs take hours, which run at the reduced scope `LONG` names.
//!
//! `MEMA_DOCS_ACTUAL=1` writes each file as its commands actually printed to
//! `target/docs-run/<file>.actual.md`, to compare with or copy from.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::util::{mema_bin, shared_data};

/// The benchmark commands whose documented runs take minutes to hours, and the arguments that
/// bound them in CI (one small cloud, one repetition). The harness appends them.
const LONG: &[(&str, &str)] = &[
    (
        "scripts/bench.sh --only fidelity",
        "--clouds car6.pcd --budgets 2400",
    ),
    (
        "scripts/bench.sh --only python",
        "--clouds car6.pcd --repeat 1",
    ),
    (
        "mema bench --data ../shared/data --only pipeline",
        "--clouds car6.pcd --repeat 1",
    ),
    (
        "mema bench --data ../shared/data",
        "--clouds car6.pcd --repeat 1",
    ),
    ("mema bench --only fitness", "--repeat 1"),
];

/// The longest any one documented command may take.
const COMMAND_LIMIT: Duration = Duration::from_secs(900);

#[derive(Debug)]
struct Step {
    line: usize,
    command: String,
    status: i32,
    output: Vec<String>,
}

/// The console blocks' commands of one Markdown file, in order; an error for a shell block.
fn steps_of(text: &str, name: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    let mut lines = text.lines().enumerate().peekable();
    while let Some((n, line)) = lines.next() {
        let Some(info) = line.trim_start().strip_prefix("```") else {
            continue;
        };
        let lang = info.split([',', ' ']).next().unwrap_or("");
        if matches!(lang, "sh" | "bash" | "shell" | "zsh") {
            return Err(format!(
                "{name}:{}: a ```{lang} block; commands go in ```console blocks, which are run",
                n + 1
            ));
        }
        let mut block = Vec::new();
        for (m, inner) in lines.by_ref() {
            if inner.trim_start().starts_with("```") {
                break;
            }
            block.push((m, inner));
        }
        if lang != "console" {
            continue;
        }
        let mut i = 0;
        while i < block.len() {
            let (m, inner) = block[i];
            let Some(first) = inner.strip_prefix("$ ") else {
                return Err(format!(
                    "{name}:{}: output before any command in a console block",
                    m + 1
                ));
            };
            let mut command = first.to_string();
            while command.ends_with('\\') && i + 1 < block.len() {
                i += 1;
                command.push('\n');
                command.push_str(block[i].1);
            }
            i += 1;
            let mut status = 0;
            if let Some(code) = block.get(i).and_then(|(_, l)| l.strip_prefix("? ")) {
                status = code
                    .trim()
                    .parse()
                    .map_err(|_| format!("{name}:{}: `? {code}` is no status", block[i].0 + 1))?;
                i += 1;
            }
            let mut output = Vec::new();
            while i < block.len() && !block[i].1.starts_with("$ ") {
                output.push(block[i].1.to_string());
                i += 1;
            }
            steps.push(Step {
                line: m + 1,
                command,
                status,
                output,
            });
        }
    }
    Ok(steps)
}

/// Whether `actual` matches the documented `pattern` (`[..]`: any text).
fn line_matches(pattern: &str, actual: &str) -> bool {
    let pattern = pattern.trim_end();
    let actual = actual.trim_end();
    let pieces: Vec<&str> = pattern.split("[..]").collect();
    if pieces.len() == 1 {
        return pattern == actual;
    }
    let (first, last) = (pieces[0], pieces[pieces.len() - 1]);
    if !actual.starts_with(first) || actual.len() < first.len() + last.len() {
        return false;
    }
    let mut rest = &actual[first.len()..];
    for piece in &pieces[1..pieces.len() - 1] {
        match rest.find(piece) {
            Some(at) => rest = &rest[at + piece.len()..],
            None => return false,
        }
    }
    rest.ends_with(last)
}

/// Whether the output's lines match the documented ones (`...`: any number of lines).
fn output_matches(pattern: &[String], actual: &[&str]) -> bool {
    match pattern.split_first() {
        None => actual.is_empty(),
        Some((first, rest)) if first.trim() == "..." => {
            (0..=actual.len()).any(|skip| output_matches(rest, &actual[skip..]))
        }
        Some((first, rest)) => {
            !actual.is_empty()
                && line_matches(first, actual[0])
                && output_matches(rest, &actual[1..])
        }
    }
}

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .expect("repository root")
}

/// A scratch checkout: the repository's entries and `../shared` as symlinks.
fn scratch_checkout(name: &str) -> PathBuf {
    let root = repository();
    let base = root.join("target/docs-run").join(name);
    let _ = std::fs::remove_dir_all(&base);
    let checkout = base.join("checkout");
    std::fs::create_dir_all(&checkout).expect("scratch checkout");
    let shared = shared_data().join("..").canonicalize().expect("../shared");
    std::os::unix::fs::symlink(shared, base.join("shared")).expect("link ../shared");
    for entry in std::fs::read_dir(&root).expect("repository") {
        let entry = entry.expect("entry");
        let file = entry.file_name();
        if file == ".git" {
            continue;
        }
        std::os::unix::fs::symlink(entry.path(), checkout.join(&file)).expect("link entry");
    }
    checkout
}

/// What a documented command is run as: the LONG ones at their reduced scope.
fn as_run(command: &str) -> String {
    for (prefix, bound) in LONG {
        if let Some(rest) = command.strip_prefix(prefix) {
            let (args, comment) = match rest.find(" #") {
                Some(at) => rest.split_at(at),
                None => (rest, ""),
            };
            return format!("{prefix}{args} {bound}{comment}");
        }
    }
    command.to_string()
}

/// Runs one file's commands; the failures, each with what was documented and what came.
fn run_file(relative: &str) -> Vec<String> {
    let root = repository();
    let text = std::fs::read_to_string(root.join(relative)).expect("documentation file");
    let steps = match steps_of(&text, relative) {
        Ok(steps) => steps,
        Err(e) => return vec![e],
    };
    let name = relative.replace('/', "-");
    let checkout = scratch_checkout(&name);
    let bin_dir = mema_bin().parent().expect("target/release").to_path_buf();
    // Beside the checkout, spelled without `..`: cargo compares the install root's `bin` with
    // the PATH's entries as written, and warns when it finds it on none (a user's is on it).
    let cargo_home = checkout.parent().expect("scratch base").join("cargo-home");
    let path = format!(
        "{}:{}:{}:{}",
        cargo_home.join("bin").display(),
        bin_dir.display(),
        root.join("target/py-venv/bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut failures = Vec::new();
    let mut groups = Vec::new();
    let mut actual_doc = String::new();
    for step in &steps {
        if step.command.trim() == "scripts/test.sh" {
            continue;
        }
        let log = checkout.join(format!("../step-{}.log", step.line));
        let file = std::fs::File::create(&log).expect("log file");
        let run = as_run(&step.command);
        let started = Instant::now();
        let mut child = {
            use std::os::unix::process::CommandExt;
            Command::new("bash")
                .arg("-c")
                .arg(&run)
                .current_dir(&checkout)
                .env("PATH", &path)
                .env("CARGO_TARGET_DIR", root.join("target/docs-cargo"))
                .env("CARGO_INSTALL_ROOT", &cargo_home)
                .env("MEMA_PY", root.join("target/py-venv/bin/python"))
                .env_remove("RUST_BACKTRACE")
                .stdin(std::process::Stdio::null())
                .stdout(file.try_clone().expect("log"))
                .stderr(file)
                .process_group(0)
                .spawn()
                .expect("bash")
        };
        groups.push(child.id());
        let status = loop {
            if let Some(status) = child.try_wait().expect("wait") {
                break status.code().unwrap_or(-1);
            }
            if started.elapsed() > COMMAND_LIMIT {
                let _ = child.kill();
                break -1;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let output = std::fs::read_to_string(&log).unwrap_or_default();
        let lines: Vec<&str> = output.lines().collect();
        actual_doc.push_str(&format!(
            "{relative}:{}\n$ {}\n? {status}\n{output}\n",
            step.line, step.command
        ));
        let output_ok = output_matches(&step.output, &lines);
        if status != step.status || !output_ok {
            failures.push(format!(
                "{relative}:{}: `{}` (run as `{run}`)\n  documented: status {}{}\n  came: status {status}, output:\n{output}",
                step.line,
                step.command,
                step.status,
                if step.output.is_empty() {
                    ", no output".to_string()
                } else {
                    format!(", output:\n{}", step.output.join("\n"))
                },
            ));
        }
    }
    for group in groups {
        let _ = Command::new("kill")
            .args(["-TERM", "--", &format!("-{group}")])
            .stderr(std::process::Stdio::null())
            .status();
    }
    if std::env::var_os("MEMA_DOCS_ACTUAL").is_some() {
        let out = root
            .join("target/docs-run")
            .join(format!("{name}.actual.md"));
        std::fs::write(out, actual_doc).expect("actual output");
    }
    failures
}

fn check(relative: &str) {
    let failures = run_file(relative);
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// Whether a step's documented output is `...` alone: held to its exit status, nothing compared.
fn is_bare(step: &Step) -> bool {
    !step.output.is_empty() && step.output.iter().all(|l| l.trim() == "...")
}

/// The steps of every documented file.
fn all_steps() -> Vec<(String, Vec<Step>)> {
    let root = repository();
    let mut files = vec!["README.md".to_string(), "PROTOCOL.md".to_string()];
    files.extend(GUIDES.iter().map(|g| format!("docs/{g}")));
    files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(root.join(&f)).expect("documentation file");
            let steps = steps_of(&text, &f).expect("console blocks");
            (f, steps)
        })
        .collect()
}

/// The files with no command: nothing in them is run, so no test claims them.
const NO_COMMANDS: &[&str] = &[
    "PROTOCOL.md",
    "docs/README.md",
    "docs/library.md",
    "docs/map-format.md",
    "docs/results.md",
    "docs/testing.md",
    "docs/tolerance.md",
];

#[test]
fn files_without_commands_are_not_counted_as_tested() {
    let tested: Vec<&str> = TESTED.to_vec();
    for (file, steps) in all_steps() {
        let listed = NO_COMMANDS.contains(&file.as_str());
        assert_eq!(
            steps.is_empty(),
            listed,
            "{file}: {} commands, but {} NO_COMMANDS",
            steps.len(),
            if listed { "in" } else { "not in" }
        );
        assert_eq!(
            tested.contains(&file.as_str()),
            !listed,
            "{file}: a file is tested below exactly when it has commands"
        );
        if !steps.is_empty() {
            assert!(
                steps.iter().any(|s| !is_bare(s)),
                "{file}: every command's output is `...`; show what one prints"
            );
        }
    }
}

/// Even a benchmark's lines name what it measured, and its deterministic figures (counts,
/// iterations, `same`) can be compared while its times are `[..]`.
#[test]
fn no_command_is_held_to_its_exit_status_alone() {
    let bare: Vec<String> = all_steps()
        .iter()
        .flat_map(|(file, steps)| {
            steps
                .iter()
                .filter(|s| is_bare(s))
                .map(move |s| format!("{file}:{}: {}", s.line, s.command))
        })
        .collect();
    assert!(
        bare.is_empty(),
        "{} commands show `...` alone: show the lines that matter\n{}",
        bare.len(),
        bare.join("\n")
    );
}

#[test]
fn every_guide_is_in_the_list_below() {
    let mut guides: Vec<String> = std::fs::read_dir(repository().join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".md"))
        .collect();
    guides.sort();
    assert_eq!(
        guides, GUIDES,
        "docs/ and the harness's list of guides differ"
    );
}

/// The files of docs/: the guides, each a test of its own below where it has commands, and the
/// results file the guides quote (tests/tests/results.rs).
const GUIDES: &[&str] = &[
    "README.md",
    "board.md",
    "command-line.md",
    "design.md",
    "fidelity.md",
    "firmware.md",
    "library.md",
    "map-format.md",
    "performance.md",
    "pictures-meshes.md",
    "python.md",
    "queries.md",
    "results.md",
    "ros2-bags.md",
    "streaming.md",
    "testing.md",
    "tolerance.md",
];

macro_rules! doc_tests {
    ($($test:ident => $file:expr),* $(,)?) => {
        /// The files whose commands the tests below run.
        const TESTED: &[&str] = &[$($file),*];
        $(#[test]
        fn $test() {
            check($file);
        })*
    };
}

doc_tests! {
    readme_commands_run_as_documented => "README.md",
    board_guide_runs_as_documented => "docs/board.md",
    command_line_guide_runs_as_documented => "docs/command-line.md",
    design_guide_runs_as_documented => "docs/design.md",
    fidelity_guide_runs_as_documented => "docs/fidelity.md",
    firmware_guide_runs_as_documented => "docs/firmware.md",
    performance_guide_runs_as_documented => "docs/performance.md",
    pictures_guide_runs_as_documented => "docs/pictures-meshes.md",
    python_guide_runs_as_documented => "docs/python.md",
    queries_guide_runs_as_documented => "docs/queries.md",
    ros2_bags_guide_runs_as_documented => "docs/ros2-bags.md",
    streaming_guide_runs_as_documented => "docs/streaming.md",
}

#[test]
fn the_matcher_holds_to_what_is_documented() {
    let doc = |s: &str| s.lines().map(String::from).collect::<Vec<_>>();
    assert!(output_matches(&doc("a\n...\nz"), &["a", "b", "c", "z"]));
    assert!(output_matches(&doc("a\n...\nz"), &["a", "z"]));
    assert!(!output_matches(&doc("a\n...\nz"), &["a", "b"]));
    assert!(!output_matches(&doc("a\nb"), &["a", "b", "c"]));
    assert!(line_matches(
        "took [..] s, [..] points",
        "took 1.2 s, 30 points"
    ));
    assert!(!line_matches("took [..] s", "took 1.2 ms"));
    assert!(!line_matches("k = 150", "k = 151"));
    // A command shown without output must print nothing; `...` alone takes anything.
    assert!(output_matches(&[], &[]));
    assert!(!output_matches(&[], &["car.mema"]));
    assert!(output_matches(&doc("..."), &["car.mema"]));
    assert!(line_matches(
        "[..]Installed package `mema v[..]`",
        "   Installed package `mema v0.1.0`"
    ));
    assert!(!line_matches("[..] s, 10031 points", "0.1 s, 10032 points"));
    let steps = steps_of(
        "x\n```console\n$ mema a \\\n  --b\n? 2\nerr [..]\n$ mema c\n```\n",
        "t.md",
    )
    .expect("steps");
    assert_eq!(steps.len(), 2);
    assert_eq!(steps[0].command, "mema a \\\n  --b");
    assert_eq!((steps[0].status, steps[0].output.len()), (2, 1));
    assert!(steps_of("```sh\nmema x\n```\n", "t.md").is_err());
    assert!(steps[1].output.is_empty() && !is_bare(&steps[1]));
    let bare = steps_of("```console\n$ mema x\n...\n```\n", "t.md").expect("steps");
    assert!(is_bare(&bare[0]));
}
