use std::os::unix::fs::OpenOptionsExt;

use crate::util::{Dir, MemaCommand, Ran, shared};

fn map(dir: &Dir, input: &std::path::Path, k: &str) -> MemaCommand {
    MemaCommand::new(dir)
        .arg("map")
        .arg(input)
        .args(["-k", k, "-o"])
        .arg(dir.join("out.mema"))
}

/// No map, and no temporary file either, is left behind by a failed run.
fn assert_nothing_written(dir: &Dir, inputs: &[&str]) {
    let left: Vec<String> = dir
        .listing()
        .into_iter()
        .filter(|n| !inputs.contains(&n.as_str()))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn a_file_that_is_not_a_point_cloud() {
    let dir = Dir::new("not-a-cloud");
    let mut junk = Vec::new();
    let mut s = 0x1234_5678u32;
    for _ in 0..4096 {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        junk.push((s >> 24) as u8);
    }
    let path = dir.write("random.pcd", &junk);
    map(&dir, &path, "10").run().assert_error(1, "random.pcd");
    let text = dir.write("words.xyz", b"this is a letter\nnot a cloud at all\n");
    map(&dir, &text, "10").run().assert_error(1, "words.xyz");
    assert_nothing_written(&dir, &["random.pcd", "words.xyz"]);
}

#[test]
fn an_empty_file() {
    let dir = Dir::new("empty");
    let path = dir.write("empty.ply", b"");
    map(&dir, &path, "10").run().assert_error(1, "empty.ply");
    assert_nothing_written(&dir, &["empty.ply"]);
}

#[test]
fn truncated_pcd_and_ply() {
    let dir = Dir::new("truncated");
    for (name, fraction) in [
        ("car6.pcd", 2),
        ("five_people.pcd", 3),
        ("bun_zipper.ply", 4),
        ("lamppost.pcd", 2),
    ] {
        let bytes = std::fs::read(shared(name)).expect("shared cloud");
        let cut = format!("cut-{name}");
        // Cut inside the data, and inside the header.
        let path = dir.write(&cut, &bytes[..bytes.len() / fraction]);
        map(&dir, &path, "10").run().assert_error(1, &cut);
        let header_cut = format!("header-{name}");
        let path = dir.write(&header_cut, &bytes[..40]);
        map(&dir, &path, "10").run().assert_error(1, &header_cut);
    }
}

#[test]
fn a_cloud_of_only_nan() {
    let dir = Dir::new("nan");
    let path = dir.write("nan.xyz", b"nan nan nan\nNaN 1 2\n3 nan 4\n");
    map(&dir, &path, "2").run().assert_error(1, "nan.xyz");
    let pcd = b"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\nnan nan nan\nnan nan nan\nnan nan nan\nnan nan nan\n";
    let path = dir.write("organized-nan.pcd", pcd);
    map(&dir, &path, "2")
        .run()
        .assert_error(1, "organized-nan.pcd");
}

#[test]
fn nan_points_are_dropped_and_the_rest_mapped() {
    let dir = Dir::new("some-nan");
    let mut text = String::new();
    for i in 0..200 {
        if i % 10 == 0 {
            text.push_str("nan 0 0\n");
        } else {
            text.push_str(&format!(
                "{} {} {}\n",
                (i as f64 * 0.37).sin(),
                (i as f64 * 0.11).cos(),
                i as f64 * 0.01
            ));
        }
    }
    let path = dir.write("some.xyz", text.as_bytes());
    let ran = map(&dir, &path, "5").arg("--json").run().assert_ok();
    let v = ran.json();
    assert_eq!(v["memory"]["points"], 180);
    assert_eq!(v["dropped_non_finite"], 20);
}

#[test]
fn k_zero_and_k_larger_than_the_cloud() {
    let dir = Dir::new("k");
    let car = shared("car6.pcd");
    map(&dir, &car, "0")
        .run()
        .assert_error(2, "k must be at least 1");
    map(&dir, &car, "10032")
        .run()
        .assert_error(1, "larger than the cloud");
    // Ten points, two of them distinct: k = 3 cannot place three distinct centres.
    let path = dir.write(
        "dup.xyz",
        b"1 2 3\n1 2 3\n1 2 3\n1 2 3\n1 2 3\n4 5 6\n4 5 6\n4 5 6\n4 5 6\n4 5 6\n",
    );
    map(&dir, &path, "3")
        .run()
        .assert_error(1, "distinct points");
    assert_nothing_written(&dir, &["dup.xyz"]);
}

#[test]
fn bad_option_values_are_usage_errors() {
    let dir = Dir::new("usage");
    let car = shared("car6.pcd");
    map(&dir, &car, "10")
        .args(["--alpha", "1.5"])
        .run()
        .assert_error(2, "--alpha");
    map(&dir, &car, "10")
        .arg("--threshold=-1")
        .run()
        .assert_error(2, "--threshold");
}

#[test]
fn an_unwritable_output_directory() {
    let dir = Dir::new("out-dir");
    let car = shared("car6.pcd");
    let missing = dir.join("no/such/dir/map.mema");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "10", "-o"])
        .arg(&missing)
        .run()
        .assert_error(1, "no/such/dir does not exist");
    // A regular file where a directory should be: tests run as root, so permission bits alone
    // would not stop the write.
    let file = dir.write("plain-file", b"x");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "10", "-o"])
        .arg(file.join("map.mema"))
        .run()
        .assert_error(1, "plain-file is not a directory");
    assert_eq!(dir.listing(), vec!["plain-file".to_string()]);
    // --labels where it cannot go fails before any work, naming the labels, and writes no map.
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "10", "-o"])
        .arg(dir.join("map.mema"))
        .arg("--labels")
        .arg(dir.join("gone/labels.txt"))
        .run()
        .assert_error(1, "cannot write labels");
    assert_eq!(dir.listing(), vec!["plain-file".to_string()]);
    // A picture that cannot be written says so, not "map".
    MemaCommand::new(&dir)
        .args(["map", "--paper", "-k", "10", "-o", "m.mema"])
        .arg(&car)
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .arg("draw")
        .arg(&car)
        .arg("m.mema")
        .arg("-o")
        .arg(file.join("p.png"))
        .run()
        .assert_error(1, "cannot write picture");
}

#[test]
fn unknown_map_extension_and_corrupt_map() {
    let dir = Dir::new("map-files");
    let car = shared("car6.pcd");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "10", "-o"])
        .arg(dir.join("map.txt"))
        .run()
        .assert_error(2, "map.txt");
    let good = dir.join("m.mema");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&car)
        .args(["-k", "10", "-o"])
        .arg(&good)
        .run()
        .assert_ok();
    let mut bytes = std::fs::read(&good).expect("map");
    bytes[50] ^= 0x10;
    let bad = dir.write("bad.mema", &bytes);
    MemaCommand::new(&dir)
        .arg("info")
        .arg(&bad)
        .run()
        .assert_error(1, "checksum");
    MemaCommand::new(&dir)
        .arg("eval")
        .arg(&car)
        .arg(&bad)
        .run()
        .assert_error(1, "bad.mema");
    for samples in ["0", "100000001"] {
        MemaCommand::new(&dir)
            .arg("eval")
            .arg(&car)
            .arg(&good)
            .args(["--samples", samples])
            .run()
            .assert_error(2, "--samples");
    }
}

#[test]
fn a_voxel_too_small_for_the_cloud_is_refused_not_collapsed() {
    let dir = Dir::new("voxel-tiny");
    // 1e-30 m voxels on a bunny put indices past 2^53: f64 cannot keep them apart.
    map(&dir, &shared("bun_zipper.ply"), "10")
        .args(["--voxel", "1e-30"])
        .run()
        .assert_error(1, "too small for this cloud");
    assert_nothing_written(&dir, &[]);
    // The smallest usable size it suggests works.
    map(&dir, &shared("bun_zipper.ply"), "10")
        .args(["--voxel", "1e-12"])
        .run()
        .assert_ok();
}

/// A cloud spanning nearly the whole f32 range: every k, one cluster included, refuses it
/// instead of writing an infinite entity with error 0.
#[test]
fn a_cloud_too_wide_for_f32_distances() {
    let dir = Dir::new("too-wide");
    // Every point 3.4e38 m from the next: none is isolated, and no f32 distance holds them.
    let mut corners = String::new();
    for i in 0..8 {
        let c = |bit: i32| {
            if i >> bit & 1 == 1 {
                "3.4e38"
            } else {
                "-3.4e38"
            }
        };
        corners.push_str(&format!("{} {} {}\n", c(0), c(1), c(2)));
    }
    let path = dir.write("wide.xyz", corners.as_bytes());
    for k in ["1", "2"] {
        for model in ["shells", "paper"] {
            for outliers in ["20,30", "off"] {
                map(&dir, &path, k)
                    .args(["--model", model, "--outliers", outliers])
                    .run()
                    .assert_error(1, "squared distances would overflow");
            }
        }
    }
    assert_nothing_written(&dir, &["wide.xyz"]);
    // Two points 3.4e38 m out beside four within 2 m: isolated, they are dropped; kept, they
    // are every point's neighbours in a cloud this small, and k-means refuses the distances.
    let path = dir.write(
        "strays.xyz",
        b"-3.4e38 0 0\n3.4e38 0 0\n0 1 0\n0 0 1\n1 1 1\n2 0 1\n",
    );
    map(&dir, &path, "1")
        .args(["--outliers", "off"])
        .run()
        .assert_error(1, "squared distances would overflow");
    assert_nothing_written(&dir, &["wide.xyz", "strays.xyz"]);
    let ran = map(&dir, &path, "1").run().assert_ok();
    assert!(
        ran.stderr().contains("dropped 2 isolated points"),
        "{}",
        ran.stderr()
    );
}

/// Inputs that never end: a capture linked to /dev/zero is read only up to a stated limit, and a
/// FIFO that nobody writes to ends in an error after the idle timeout (it used to hang `map` and
/// `info` forever, and `info`/`replay` on /dev/zero grew until memory ran out).
#[test]
fn endless_and_silent_inputs_end_in_one_line_errors() {
    let dir = Dir::new("endless");
    let zero_capture = dir.join("zero.bin");
    std::os::unix::fs::symlink("/dev/zero", &zero_capture).expect("symlink");
    MemaCommand::new(&dir)
        .args(["replay", "-k", "10", "-o"])
        .arg(dir.join("replayed.mema"))
        .arg(&zero_capture)
        .run()
        .assert_error(1, "too large");
    for (name, command) in [("quiet.mema", "info"), ("quiet.xyz", "map")] {
        let fifo = dir.join(name);
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .expect("mkfifo runs");
        assert!(made.success());
        let started = std::time::Instant::now();
        let mut run = MemaCommand::new(&dir).arg(command).arg(&fifo);
        if command == "map" {
            run = run.args(["-k", "2", "-o"]).arg(dir.join("out.mema"));
        }
        run.run().assert_error(1, "nothing arrived");
        assert!(
            started.elapsed() < std::time::Duration::from_secs(60),
            "{command} waited {:?}",
            started.elapsed()
        );
    }
}

/// A /proc file reports length 0 but has bytes: it is read, and judged by what it holds (it was
/// "an empty file"); a truly empty file is still one.
#[test]
fn a_proc_file_is_read_for_what_it_holds() {
    let dir = Dir::new("proc-file");
    let ran = map(&dir, std::path::Path::new("/proc/cpuinfo"), "2")
        .run()
        .assert_error(1, "/proc/cpuinfo: not a point cloud");
    assert!(!ran.stderr().contains("empty"), "{}", ran.stderr());
    let empty = dir.write("empty.xyz", b"");
    map(&dir, &empty, "2").run().assert_error(1, "empty file");
}

/// A map past the query index's 16,384 entities names its file in the error (it did not).
#[test]
fn a_map_too_large_for_the_query_index_is_named() {
    let dir = Dir::new("big-query");
    let mut csv = String::from("cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind\n");
    for i in 0..16_385 {
        csv.push_str(&format!("{i},0,0,0.1,0.1,0.1,0,0,0,1,ellipsoid\n"));
    }
    let big = dir.write("big.csv", csv.as_bytes());
    MemaCommand::new(&dir)
        .arg("query")
        .arg(&big)
        .args(["--point", "0,0,0"])
        .run()
        .assert_error(1, "big.csv: ");
}

/// The bytes a `mema info` of a `.mema` FIFO took from `source` before refusing it, and its run.
fn bytes_taken_by_info(dir: &Dir, name: &str, source: &'static str) -> (u64, Ran) {
    use std::io::{Read, Write};
    let fifo = dir.join(name);
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let path = fifo.clone();
    let writer = std::thread::spawn(move || {
        let mut from = std::fs::File::open(source).expect("source device");
        let mut to = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("fifo opens for writing");
        let (mut chunk, mut taken) = (vec![0u8; 4096], 0u64);
        // Bounded, so that a reader that never refuses fails the assertion, not the run.
        while taken < 64 << 20 {
            from.read_exact(&mut chunk).expect("source bytes");
            match to.write(&chunk) {
                Ok(n) => taken += n as u64,
                Err(_) => break,
            }
        }
        taken
    });
    let ran = MemaCommand::new(dir).arg("info").arg(&fifo).run();
    // Were mema to end before opening the FIFO, this open releases the writer's (O_NONBLOCK,
    // so that it never waits itself).
    let unblock = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(0o4000)
        .open(&fifo);
    drop(unblock);
    (writer.join().expect("writer"), ran)
}

/// A map is refused from its first bytes: `/dev/zero` or `/dev/urandom` given as a map is
/// refused within 1 MB of reading (the whole 1 GiB limit was read before).
#[test]
fn a_map_is_refused_from_its_first_bytes() {
    let dir = Dir::new("map-start");
    for (name, source) in [("zero.mema", "/dev/zero"), ("random.mema", "/dev/urandom")] {
        let (taken, ran) = bytes_taken_by_info(&dir, name, source);
        ran.assert_error(1, "not a map: it starts with");
        // The pipe's own buffer holds what mema never read: the bound is on both together.
        assert!(taken < 1_000_000, "{source}: {taken} bytes taken");
    }
    for (name, said) in [
        ("zero.csv", "a CSV map is ASCII text"),
        ("zero.json", "a JSON map starts with '{'"),
    ] {
        let link = dir.join(name);
        std::os::unix::fs::symlink("/dev/zero", &link).expect("symlink");
        let ran = MemaCommand::new(&dir).arg("info").arg(&link).run();
        ran.assert_error(1, said);
    }
}

/// A reader that goes away (`mema info MAP | head -1`) ends mema as it ends Unix tools: no
/// message, killed by SIGPIPE (it printed "internal error: failed printing to stdout").
#[test]
fn a_closed_pipe_ends_quietly_as_unix_tools_do() {
    use std::os::unix::process::ExitStatusExt;
    let dir = Dir::new("closed-pipe");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("car6.pcd"))
        .args(["-k", "150", "-o", "car6.mema"])
        .run()
        .assert_ok();
    for args in [
        &["info", "car6.mema"][..],
        &["info", "car6.mema", "--json"],
        &["man"],
    ] {
        let (reader, writer) = std::io::pipe().expect("pipe");
        drop(reader);
        let out = std::process::Command::new(crate::util::mema_bin())
            .args(args)
            .current_dir(&dir.path)
            .stdout(writer)
            .output()
            .expect("mema runs");
        assert_eq!(out.status.signal(), Some(13), "{args:?}: {:?}", out.status);
        assert!(
            out.stderr.is_empty(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let shell = std::process::Command::new("bash")
        .arg("-c")
        .arg(format!(
            "{} info car6.mema | head -1; echo \"status ${{PIPESTATUS[0]}}\" >&2",
            crate::util::mema_bin().display()
        ))
        .current_dir(&dir.path)
        .output()
        .expect("bash runs");
    let stdout = String::from_utf8_lossy(&shell.stdout);
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(stdout.starts_with("car6.mema: 150 entities"), "{stdout}");
    let stderr = String::from_utf8_lossy(&shell.stderr);
    // 0 when all of it fit in the pipe before head left, 141 (128 + SIGPIPE) when it did not.
    assert!(
        stderr == "status 0\n" || stderr == "status 141\n",
        "{stderr}"
    );
}
