//! The serial path end to end over a real pseudo-terminal pair (socat, installed by
//! scripts/test.sh): `scanner-sim` on one end, `stream` on the other.

use crate::util::{Dir, MemaCommand, mema_bin, shared};
use mema::io::load_cloud;
use mema::link::stream::Capacity;
use mema::link::stream::{map_sent_directly_with, stream_params};
use mema_core::stream::StreamModel;
use std::io::Read;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A socat-made pty pair, killed on drop.
pub(crate) struct PtyPair {
    child: Child,
    pub a: PathBuf,
    pub b: PathBuf,
}

impl PtyPair {
    pub(crate) fn new(dir: &Dir) -> Self {
        Self::named(dir, "tty")
    }

    /// A pair linked at `{name}A` and `{name}B` in `dir` (two pairs in one directory).
    pub(crate) fn named(dir: &Dir, name: &str) -> Self {
        let (a, b) = (dir.join(&format!("{name}A")), dir.join(&format!("{name}B")));
        let child = Command::new("socat")
            .arg(format!("pty,raw,echo=0,link={}", a.display()))
            .arg(format!("pty,raw,echo=0,link={}", b.display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("socat runs (scripts/test.sh installs it)");
        let deadline = Instant::now() + Duration::from_secs(10);
        while !(a.exists() && b.exists()) {
            assert!(Instant::now() < deadline, "socat made no ptys");
            std::thread::sleep(Duration::from_millis(20));
        }
        Self { child, a, b }
    }

    pub(crate) fn unplug(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for PtyPair {
    fn drop(&mut self) {
        self.unplug();
    }
}

/// A running `mema` whose stderr is collected as it arrives.
pub(crate) struct Running {
    child: Child,
    stderr: Arc<Mutex<String>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

pub(crate) fn spawn_mema(dir: &Dir, args: &[&str]) -> Running {
    let mut child = Command::new(mema_bin())
        .args(args)
        .current_dir(&dir.path)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mema runs");
    let stderr = Arc::new(Mutex::new(String::new()));
    let sink = stderr.clone();
    let mut pipe = child.stderr.take().expect("stderr piped");
    let reader = std::thread::spawn(move || {
        let mut buf = [0u8; 1024];
        while let Ok(n) = pipe.read(&mut buf) {
            if n == 0 {
                break;
            }
            sink.lock()
                .expect("lock")
                .push_str(&String::from_utf8_lossy(&buf[..n]));
        }
    });
    Running {
        child,
        stderr,
        reader: Some(reader),
    }
}

impl Running {
    /// Blocks until the command has opened its port (it says so on stderr).
    pub(crate) fn wait_until_listening(&self) {
        let deadline = Instant::now() + Duration::from_secs(30);
        while !self.stderr.lock().expect("lock").contains("listening on") {
            assert!(
                Instant::now() < deadline,
                "mema never opened its port: {}",
                self.stderr.lock().expect("lock")
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    pub(crate) fn id(&self) -> u32 {
        self.child.id()
    }

    /// Blocks until stderr holds `needle` (a hang is a failure).
    pub(crate) fn wait_for(&self, needle: &str) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while !self.stderr.lock().expect("lock").contains(needle) {
            assert!(
                Instant::now() < deadline,
                "mema never said {needle:?}: {}",
                self.stderr.lock().expect("lock")
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

/// Waits for the command up to `limit`; a hang is a failure, never a stuck test run.
pub(crate) fn finish(mut running: Running, limit: Duration) -> (i32, String, String) {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = running.child.try_wait().expect("wait") {
            let mut stdout = String::new();
            if let Some(mut out) = running.child.stdout.take() {
                out.read_to_string(&mut stdout).expect("stdout");
            }
            if let Some(reader) = running.reader.take() {
                reader.join().expect("stderr reader");
            }
            let stderr = running.stderr.lock().expect("lock").clone();
            return (status.code().unwrap_or(-1), stdout, stderr);
        }
        if Instant::now() > deadline {
            let _ = running.child.kill();
            panic!("mema did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The CLI's default fit parameters, exactly as `mema stream -k 150` builds them (the CLI's
/// flags default to the library's `FitOptions::default()`, checked by its own unit test).
fn default_fit() -> mema_core::fit::FitParams {
    mema::mapping::FitOptions::default()
        .config(150)
        .expect("valid defaults")
        .fit
}

#[test]
fn pty_stream_equals_replay_and_the_direct_mapper() {
    let dir = Dir::new("pty");
    let car = shared("car6.pcd");
    let mut pty = PtyPair::new(&dir);
    let stream = spawn_mema(
        &dir,
        &[
            "stream",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-k",
            "150",
            "--model",
            "paper",
            "-o",
            "stream.mema",
            "--record",
            "wire.bin",
        ],
    );
    stream.wait_until_listening();
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .arg("--port")
        .arg(&pty.a)
        .arg(&car)
        .args(["--chunk-bytes", "61"])
        .run()
        .assert_ok();
    let (code, stdout, stderr) = finish(stream, Duration::from_secs(60));
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(stdout.trim(), "stream.mema", "the map path on stdout");
    assert!(
        // 101 frames of points after the pose frame of the sensor at the car's centre.
        stderr.contains("10031 points") && stderr.contains("102 accepted / 0 rejected / 0 lost"),
        "{stderr}"
    );
    pty.unplug();

    MemaCommand::new(&dir)
        .args(["replay", "wire.bin", "-k", "150", "--model", "paper"])
        .args(["-o", "replay.mema"])
        .run()
        .assert_ok();
    let streamed = std::fs::read(dir.join("stream.mema")).expect("stream map");
    assert_eq!(
        streamed,
        std::fs::read(dir.join("replay.mema")).expect("replay map"),
        "stream vs replay"
    );

    let cloud = load_cloud(&car).expect("car6");
    let paper = |capacity| stream_params(capacity, 0, default_fit(), 0.0, StreamModel::Paper);
    let direct =
        map_sent_directly_with(&cloud, paper(Capacity::all_working(150))).expect("direct map");
    assert_eq!(
        streamed,
        direct.to_mema().expect("encode"),
        "stream vs the mapper fed directly"
    );
    // The stream's map holds real ellipsoids of the car: at most k, and most of the capacity.
    assert!(
        (120..=150).contains(&direct.entities.len()),
        "{}",
        direct.entities.len()
    );

    // The recorded bytes are exactly what the scanner sends (its capture-file mode).
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .args(["--port", "file.bin"])
        .arg(&car)
        .run()
        .assert_ok();
    assert_eq!(
        std::fs::read(dir.join("wire.bin")).expect("recorded"),
        std::fs::read(dir.join("file.bin")).expect("file")
    );
}

#[test]
fn unplugging_mid_stream_keeps_the_map_of_what_arrived() {
    let dir = Dir::new("unplug");
    let mut pty = PtyPair::new(&dir);
    let stream = spawn_mema(
        &dir,
        &[
            "stream",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-k",
            "100",
            "-o",
            "map.mema",
            "--record",
            "got.bin",
        ],
    );
    stream.wait_until_listening();
    // About 1.5 s of points at 24,000 points/s; the cable is pulled after 0.4 s.
    let scanner = spawn_mema(
        &dir,
        &[
            "scanner-sim",
            "--port",
            pty.a.to_str().expect("utf8"),
            shared("bun_zipper.ply").to_str().expect("utf8"),
            "--rate",
            "24000",
        ],
    );
    std::thread::sleep(Duration::from_millis(400));
    pty.unplug();
    let (code, _, stderr) = finish(stream, Duration::from_secs(30));
    let _ = finish(scanner, Duration::from_secs(30));
    assert_eq!(code, 3, "documented status for a lost link:\n{stderr}");
    assert!(
        stderr.contains("link lost before end of stream"),
        "{stderr}"
    );
    let listing = dir.listing();
    assert!(
        !listing.iter().any(|n| n.ends_with(".tmp")),
        "temporary files left: {listing:?}"
    );
    let map =
        mema::io::mapfile::HostMap::read(&dir.join("map.mema")).expect("a valid map was written");
    assert!(!map.entities.is_empty() && map.entities.len() <= 100);
    // It is the map of exactly the bytes that arrived.
    let replay = MemaCommand::new(&dir)
        .args(["replay", "got.bin", "-k", "100", "-o", "replay.mema"])
        .run();
    assert_eq!(replay.output.status.code(), Some(3), "{}", replay.stderr());
    assert_eq!(
        std::fs::read(dir.join("map.mema")).expect("map"),
        std::fs::read(dir.join("replay.mema")).expect("replay")
    );
    let arrived = std::fs::metadata(dir.join("got.bin"))
        .expect("capture")
        .len();
    assert!(
        arrived > 0 && arrived < 400_000,
        "{arrived} bytes: not a partial stream"
    );
}

#[test]
fn ctrl_c_ends_the_stream_cleanly() {
    let dir = Dir::new("ctrl-c");
    let pty = PtyPair::new(&dir);
    let stream = spawn_mema(
        &dir,
        &[
            "stream",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-k",
            "10",
            "-o",
            "map.mema",
        ],
    );
    stream.wait_until_listening();
    let status = Command::new("kill")
        .args(["-INT", &stream.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let (code, stdout, stderr) = finish(stream, Duration::from_secs(10));
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    assert_eq!(stdout.trim(), "map.mema");
    let map = mema::io::mapfile::HostMap::read(&dir.join("map.mema")).expect("valid empty map");
    assert!(map.entities.is_empty());
}

#[test]
fn record_saves_exactly_the_bytes_sent() {
    let dir = Dir::new("record");
    let mut pty = PtyPair::new(&dir);
    let record = spawn_mema(
        &dir,
        &[
            "record",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-o",
            "capture.bin",
        ],
    );
    record.wait_until_listening();
    let lamppost = shared("lamppost.pcd");
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .arg("--port")
        .arg(&pty.a)
        .arg(&lamppost)
        .args(["--chunk-bytes", "7"])
        .run()
        .assert_ok();
    let (code, stdout, stderr) = finish(record, Duration::from_secs(30));
    assert_eq!(code, 0, "{stderr}");
    assert_eq!(stdout.trim(), "capture.bin");
    assert!(stderr.contains("end of stream"), "{stderr}");
    pty.unplug();
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .args(["--port", "sent.bin"])
        .arg(&lamppost)
        .run()
        .assert_ok();
    assert_eq!(
        std::fs::read(dir.join("capture.bin")).expect("capture"),
        std::fs::read(dir.join("sent.bin")).expect("sent")
    );
}

/// `--working W`: k ellipsoids with only W clusters in working memory. The map holds more than W
/// entities (the frozen ones) and at most k, replay equals the mapper fed directly, and
/// impossible shapes are usage errors.
#[test]
fn working_memory_smaller_than_k_freezes_and_stays_within_k() {
    let dir = Dir::new("stream-working");
    let car = shared("car6.pcd");
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .args(["--port", "car.bin"])
        .arg(&car)
        .run()
        .assert_ok();
    MemaCommand::new(&dir)
        .args([
            "replay",
            "car.bin",
            "-k",
            "400",
            "--working",
            "150",
            "--model",
            "paper",
            "-o",
            "w.mema",
        ])
        .run()
        .assert_ok();
    let replayed = std::fs::read(dir.join("w.mema")).expect("replay map");
    let cloud = load_cloud(&car).expect("car6");
    let capacity = Capacity {
        k: 400,
        working: 150,
    };
    let params = stream_params(capacity, 0, default_fit(), 0.0, StreamModel::Paper);
    let direct = map_sent_directly_with(&cloud, params).expect("direct map");
    assert_eq!(replayed, direct.to_mema().expect("encode"));
    let n = direct.entities.len();
    assert!(150 < n && n <= 400, "{n} entities");
    for (args, needle) in [
        (vec!["--working", "0"], "--working 0"),
        (vec!["--working", "401"], "--working 401"),
        (
            vec!["--working", "150", "--tolerance", "0.05"],
            "do not combine",
        ),
    ] {
        MemaCommand::new(&dir)
            .args(["replay", "car.bin", "-k", "400", "-o", "bad.mema"])
            .args(args)
            .run()
            .assert_error(2, needle);
    }
}

/// `stream`'s points/s counts the time the points took to arrive, not the wait before the
/// scanner started: with a pause of `WAIT` before the first byte, the rate is at least the
/// points over what is left of the run once the pause is taken out (the first point cannot
/// arrive before the scanner sends it).
#[test]
fn stream_rate_leaves_out_the_wait_for_the_first_point() {
    const WAIT: Duration = Duration::from_secs(2);
    let dir = Dir::new("stream-rate");
    let mut pty = PtyPair::new(&dir);
    let stream = spawn_mema(
        &dir,
        &[
            "stream",
            "--port",
            pty.b.to_str().expect("utf8"),
            "-k",
            "100",
            "-o",
            "map.mema",
            "--json",
        ],
    );
    stream.wait_until_listening();
    std::thread::sleep(WAIT);
    MemaCommand::new(&dir)
        .arg("scanner-sim")
        .arg("--port")
        .arg(&pty.a)
        .arg(shared("car6.pcd"))
        .run()
        .assert_ok();
    let (code, stdout, stderr) = finish(stream, Duration::from_secs(60));
    assert_eq!(code, 0, "{stderr}");
    pty.unplug();
    let s: serde_json::Value = serde_json::from_str(&stdout).expect("summary JSON");
    let number = |key: &str| s[key].as_f64().unwrap_or_else(|| panic!("{key}: {s}"));
    let (points, elapsed) = (number("points"), number("elapsed_s"));
    let (arrival, rate) = (number("arrival_s"), number("points_per_s"));
    assert_eq!(points, 10_031.0);
    assert!(
        arrival > 0.0 && arrival <= elapsed - WAIT.as_secs_f64(),
        "{s}"
    );
    assert!((rate * arrival / points - 1.0).abs() < 1e-9, "{s}");
    assert!(
        rate >= points / (elapsed - WAIT.as_secs_f64()),
        "the wait diluted the rate: {s}"
    );
    assert!(stderr.contains("points/s over the"), "{stderr}");
}
