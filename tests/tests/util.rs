use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The shared real clouds, read in place (never copied into the repository).
pub fn shared_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

pub fn shared(name: &str) -> PathBuf {
    shared_data().join(name)
}

/// The `mema` binary cargo built for this test run (same profile, beside `deps/`).
pub fn mema_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>");
    let bin = dir.join(format!("mema{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.exists(),
        "{} not built; run through `cargo test --workspace`",
        bin.display()
    );
    bin
}

/// A fresh directory per test, removed when the test ends.
pub struct Dir {
    pub path: PathBuf,
}

impl Dir {
    pub fn new(name: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::SeqCst);
        let path =
            std::env::temp_dir().join(format!("mema-test-{}-{name}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).expect("create test dir");
        Self { path }
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }

    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.join(name);
        std::fs::write(&p, bytes).expect("write test file");
        p
    }

    pub fn listing(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.path)
            .expect("ls")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// `mema` with arguments, run in a directory; assertions print everything on failure.
pub struct MemaCommand {
    args: Vec<String>,
    cwd: PathBuf,
    stdin: Stdin,
}

/// What `mema` reads on its standard input.
enum Stdin {
    /// Nothing: a closed stream.
    Closed,
    /// A file, as `< file` redirects it.
    File(PathBuf),
    /// Bytes through a pipe, written as `mema` reads them.
    Pipe(Vec<u8>),
}

pub struct Ran {
    pub output: Output,
    pub description: String,
}

impl MemaCommand {
    pub fn new(dir: &Dir) -> Self {
        Self {
            args: Vec::new(),
            cwd: dir.path.clone(),
            stdin: Stdin::Closed,
        }
    }

    /// Standard input redirected from `path`.
    pub fn stdin_file(mut self, path: impl Into<PathBuf>) -> Self {
        self.stdin = Stdin::File(path.into());
        self
    }

    /// Standard input a pipe that carries `bytes`.
    pub fn stdin_pipe(mut self, bytes: Vec<u8>) -> Self {
        self.stdin = Stdin::Pipe(bytes);
        self
    }

    pub fn arg(mut self, a: impl AsRef<std::ffi::OsStr>) -> Self {
        self.args.push(a.as_ref().to_string_lossy().into_owned());
        self
    }

    pub fn args<I: IntoIterator<Item = S>, S: AsRef<std::ffi::OsStr>>(mut self, items: I) -> Self {
        for a in items {
            self = self.arg(a);
        }
        self
    }

    pub fn run(self) -> Ran {
        let mut command = Command::new(mema_bin());
        command
            .args(&self.args)
            .current_dir(&self.cwd)
            .env("RUST_BACKTRACE", "1");
        let output = match self.stdin {
            Stdin::Closed => command.output().expect("mema runs"),
            Stdin::File(path) => command
                .stdin(std::fs::File::open(&path).expect("stdin file"))
                .output()
                .expect("mema runs"),
            Stdin::Pipe(bytes) => {
                let mut child = command
                    .stdin(Stdio::piped())
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()
                    .expect("mema runs");
                let mut pipe = child.stdin.take().expect("stdin piped");
                // A writer of its own: mema may answer (or fail) before it has read it all.
                let writer = std::thread::spawn(move || {
                    let _ = pipe.write_all(&bytes);
                });
                let output = child.wait_with_output().expect("mema runs");
                writer.join().expect("stdin writer");
                output
            }
        };
        Ran {
            output,
            description: format!("mema {} (in {})", self.args.join(" "), self.cwd.display()),
        }
    }
}

impl Ran {
    pub fn stdout(&self) -> String {
        String::from_utf8_lossy(&self.output.stdout).into_owned()
    }

    pub fn stderr(&self) -> String {
        String::from_utf8_lossy(&self.output.stderr).into_owned()
    }

    fn report(&self) -> String {
        format!(
            "{}\nstatus: {:?}\n--- stdout\n{}\n--- stderr\n{}",
            self.description,
            self.output.status.code(),
            self.stdout(),
            self.stderr()
        )
    }

    pub fn assert_ok(self) -> Self {
        assert!(
            self.output.status.success(),
            "expected success:\n{}",
            self.report()
        );
        self
    }

    /// A failure with this exit code and a one-line `mema: ...` message containing `needle`.
    pub fn assert_error(self, code: i32, needle: &str) -> Self {
        let err = self.stderr();
        assert_eq!(
            self.output.status.code(),
            Some(code),
            "exit code:\n{}",
            self.report()
        );
        assert!(
            err.contains(needle),
            "stderr lacks {needle:?}:\n{}",
            self.report()
        );
        assert!(
            err.starts_with("mema: "),
            "error not in the mema: form:\n{}",
            self.report()
        );
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "error is not one line:\n{}",
            self.report()
        );
        assert!(
            !err.contains("panicked") && !err.contains("stack backtrace"),
            "{}",
            self.report()
        );
        self
    }

    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.stdout())
            .unwrap_or_else(|e| panic!("stdout is not JSON ({e}):\n{}", self.report()))
    }
}

/// `mema eval CLOUD dir/MAP --json`'s Chamfer distance (the two-way score, metres).
pub fn eval_chamfer(dir: &Dir, cloud: &Path, map: &str) -> f64 {
    MemaCommand::new(dir)
        .arg("eval")
        .arg(cloud)
        .arg(dir.join(map))
        .arg("--json")
        .run()
        .assert_ok()
        .json()["chamfer"]
        .as_f64()
        .expect("eval --json gives chamfer")
}

/// The rotation matrix of the quaternion `(x, y, z, w)` (scalar last, normalised here), written
/// out in the tests rather than taken from the core, so checks of oriented maps do not trust the
/// code they check.
pub fn quaternion_matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [x, y, z, w] = q.map(|v| v / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}
