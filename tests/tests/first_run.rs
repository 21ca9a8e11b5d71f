//! A first run that explains itself (issue 15): the demo's files and the commands it suggests,
//! a man page per command, usage errors in one line, scanner-sim to a file, clouds on
//! standard input.

use crate::util::{Dir, MemaCommand, shared};
use mema::io::mapfile::HostMap;

/// The demo writes its scan, map and picture under `mema-demo/`, explains its numbers, and
/// every command it suggests runs as printed; the scan it wrote maps to the map it wrote.
#[test]
fn the_demo_writes_its_files_and_its_next_commands_work() {
    let dir = Dir::new("first-demo");
    let ran = MemaCommand::new(&dir).arg("demo").run().assert_ok();
    let out = ran.stdout();
    for words in ["metres", "RMS distance", "Table 2", "Table 4", "eq. 13"] {
        assert!(
            out.contains(words),
            "the demo does not say {words:?}:\n{out}"
        );
    }
    assert_eq!(dir.listing(), vec!["mema-demo".to_string()]);
    let mut files: Vec<String> = std::fs::read_dir(dir.join("mema-demo"))
        .expect("mema-demo")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["map.mema", "picture.png", "scan.ply"], "{out}");

    let map = HostMap::read(&dir.join("mema-demo/map.mema")).expect("demo map");
    let scan = mema::io::load_cloud(&dir.join("mema-demo/scan.ply")).expect("demo scan");
    assert_eq!(map.entities.len(), 250);
    assert!(
        out.contains(&format!("{} points", scan.points.len())),
        "{out}"
    );
    let picture = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(dir.join("mema-demo/picture.png")).expect("picture"),
    ))
    .read_info()
    .expect("a PNG");
    assert_eq!((picture.info().width, picture.info().height), (1200, 900));

    // The scan as written maps to the demo's map, byte for byte: it is the demo's cloud.
    MemaCommand::new(&dir)
        .args(["map", "mema-demo/scan.ply", "-k", "250", "-o", "again.mema"])
        .run()
        .assert_ok();
    assert_eq!(
        std::fs::read(dir.join("again.mema")).expect("again"),
        std::fs::read(dir.join("mema-demo/map.mema")).expect("demo map")
    );

    let next: Vec<&str> = out
        .lines()
        .filter_map(|l| l.strip_prefix("  mema "))
        .collect();
    assert!(next.len() >= 3, "no next commands:\n{out}");
    for command in next {
        MemaCommand::new(&dir)
            .args(command.split_whitespace())
            .run()
            .assert_ok();
    }
}

/// `--out-dir` is made if missing, and the text says where the files went.
#[test]
fn the_demo_writes_where_it_is_told_and_says_so() {
    let dir = Dir::new("first-demo-dir");
    let ran = MemaCommand::new(&dir)
        .args(["demo", "-k", "60", "--paper", "--out-dir", "runs/first"])
        .run()
        .assert_ok();
    assert!(ran.stdout().contains("runs/first"), "{}", ran.stdout());
    assert!(ran.stdout().contains("spherical"), "{}", ran.stdout());
    let map = HostMap::read(&dir.join("runs/first/map.mema")).expect("paper demo map");
    assert_eq!(map.entities.len(), 60);
    let json = MemaCommand::new(&dir)
        .args(["demo", "-k", "60", "--json", "--out-dir", "runs/json"])
        .run()
        .assert_ok()
        .json();
    for file in ["scan", "map", "picture"] {
        let path = json["files"][file].as_str().expect(file);
        assert!(dir.join(path).is_file(), "{path}");
    }
    // The picture shows the demo's Table 4 mean under its name, "as fitted" (it showed another
    // error, nearest-centre eq. 13, as "mean e").
    let mean = json["ellipsoidal"]["mean"].as_f64().expect("Table 4 mean");
    let title = json["picture_title"].as_str().expect("picture title");
    assert_eq!(
        title,
        format!("map.mema: 60 entities, eq. 13 as fitted {mean:.6}")
    );
}

/// `mema man --out-dir DIR` writes one page per command `mema --help` lists, each naming its
/// command; `mema man` alone still prints the main page.
#[test]
fn man_writes_a_page_per_command() {
    let dir = Dir::new("first-man");
    let help = MemaCommand::new(&dir)
        .arg("--help")
        .run()
        .assert_ok()
        .stdout();
    let commands: Vec<&str> = help
        .split("Commands:")
        .nth(1)
        .expect("a command list")
        .lines()
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .collect();
    assert!(commands.contains(&"map") && commands.contains(&"draw"));
    std::fs::create_dir(dir.join("man")).expect("man dir");
    MemaCommand::new(&dir)
        .args(["man", "--out-dir", "man"])
        .run()
        .assert_ok();
    let mut want: Vec<String> = commands.iter().map(|c| format!("mema-{c}.1")).collect();
    want.push("mema.1".into());
    want.sort();
    let mut got: Vec<String> = std::fs::read_dir(dir.join("man"))
        .expect("pages")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    got.sort();
    assert_eq!(got, want);
    for command in commands {
        let page =
            std::fs::read_to_string(dir.join(&format!("man/mema-{command}.1"))).expect("page");
        assert!(
            page.contains(&format!(".TH mema-{command} 1")),
            "{command}: not its roff page"
        );
        // The NAME section, where roff escapes each hyphen.
        let name = format!("mema-{command}").replace('-', "\\-");
        assert!(page.contains(&name), "{command}:\n{page}");
    }
    let main = MemaCommand::new(&dir).arg("man").run().assert_ok().stdout();
    assert!(main.contains(".TH mema"));
    MemaCommand::new(&dir)
        .args(["man", "--out-dir", "missing"])
        .run()
        .assert_error(2, "not an existing directory");
}

/// A usage error is one line, the problem and where the help is (clap's own ran to five).
#[test]
fn usage_errors_are_one_line_with_a_hint() {
    let dir = Dir::new("first-usage");
    let cases: [&[&str]; 6] = [
        &["map"],
        &["map", "--bogus"],
        &["mapp"],
        &["map", "x.ply", "-k", "many", "-o", "m.mema"],
        &["eval", "only-one.ply"],
        &[
            "draw", "c.ply", "m.mema", "-o", "p.png", "--view", "sideways",
        ],
    ];
    for args in cases {
        let ran = MemaCommand::new(&dir).args(args).run();
        let err = ran.stderr();
        let ran = ran.assert_error(2, "--help'");
        assert!(ran.stdout().is_empty(), "{args:?}: {}", ran.stdout());
        // The hint names the command typed, where there is one.
        if args[0] != "mapp" {
            assert!(err.contains(&format!("'mema {} --help'", args[0])), "{err}");
        }
    }
    let ran = MemaCommand::new(&dir).args(["map", "--bogus"]).run();
    assert!(ran.stderr().contains("--bounds"), "the suggestion is kept");
    // Help itself is untouched: on stdout, whole, exit 0.
    let help = MemaCommand::new(&dir)
        .args(["map", "--help"])
        .run()
        .assert_ok()
        .stdout();
    assert!(help.contains("Usage:") && help.lines().count() > 20);
}

/// scanner-sim to a path that is no device writes a capture file, says so, and the capture
/// replays to the points it says it holds.
#[test]
fn scanner_sim_to_a_file_says_it_wrote_a_capture() {
    let dir = Dir::new("first-sim");
    let ran = MemaCommand::new(&dir)
        .arg("scanner-sim")
        .arg(shared("bun_zipper.ply"))
        .args(["--port", "bunny.capture"])
        .run()
        .assert_ok();
    let err = ran.stderr();
    assert!(
        err.contains("capture file") && err.contains("mema replay bunny.capture"),
        "{err}"
    );
    let points = mema::io::load_cloud(&shared("bun_zipper.ply"))
        .expect("bunny")
        .points
        .len();
    assert!(err.contains(&format!("{points} points")), "{err}");
    let replayed = MemaCommand::new(&dir)
        .args(["replay", "bunny.capture", "-k", "40", "--json"])
        .run()
        .assert_ok()
        .json();
    assert_eq!(replayed["points"], points);
}

/// `-` is standard input: a file redirected or a pipe maps, and evaluates, as the file does.
#[test]
fn a_dash_reads_the_cloud_from_standard_input() {
    let dir = Dir::new("first-stdin");
    for name in ["bun_zipper.ply", "car6.pcd", "autzen_trim.laz"] {
        let file = shared(name);
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&file)
            .args(["-k", "60", "-o", "file.mema"])
            .run()
            .assert_ok();
        MemaCommand::new(&dir)
            .args(["map", "-", "-k", "60", "-o", "redirected.mema"])
            .stdin_file(&file)
            .run()
            .assert_ok();
        let piped = MemaCommand::new(&dir)
            .args(["map", "-", "-k", "60", "-o", "piped.mema"])
            .stdin_pipe(std::fs::read(&file).expect("cloud"))
            .run()
            .assert_ok();
        let from_file = std::fs::read(dir.join("file.mema")).expect("map");
        assert_eq!(
            from_file,
            std::fs::read(dir.join("redirected.mema")).expect("map"),
            "{name}"
        );
        assert_eq!(
            from_file,
            std::fs::read(dir.join("piped.mema")).expect("map"),
            "{name}"
        );
        assert!(piped.stdout().contains("unit:"), "{}", piped.stdout());
    }
    let eval = |input: &str, stdin: bool| {
        let command = MemaCommand::new(&dir).args(["eval", input, "file.mema", "--json"]);
        let command = if stdin {
            command.stdin_file(shared("autzen_trim.laz"))
        } else {
            command
        };
        command.run().assert_ok().json()
    };
    let from_file = eval(shared("autzen_trim.laz").to_str().expect("utf-8"), false);
    let from_stdin = eval("-", true);
    assert_eq!(from_file["mean"], from_stdin["mean"]);
    assert_eq!(from_file["chamfer"], from_stdin["chamfer"]);
    // Nothing on standard input is an empty cloud, named as standard input.
    MemaCommand::new(&dir)
        .args(["map", "-", "-k", "5", "-o", "none.mema"])
        .stdin_pipe(Vec::new())
        .run()
        .assert_error(1, "standard input");
}
