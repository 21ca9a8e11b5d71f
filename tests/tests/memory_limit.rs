//! Under a memory limit (`ulimit -v`, as a robot's supervisor or a container sets one), mapping
//! a large cloud either succeeds or fails with one line and exit status 1: never an abort
//! (134), a panic, or a backtrace, even with RUST_BACKTRACE=1. The limits step down through
//! where the reader, k-means, surface following and the thread pool each run out.

use crate::util::{Dir, mema_bin, shared};
use std::process::Command;

#[test]
fn a_memory_limit_gives_one_line_and_exit_1_never_an_abort() {
    let dir = Dir::new("memory-limit");
    let out = dir.join("office1.mema");
    let mut allocator_refusals = 0;
    let mut successes = 0;
    for limit_kb in (10_000..=32_000).rev().step_by(2_000) {
        let script = format!("ulimit -v {limit_kb} && exec \"$0\" map \"$1\" -k 200 -o \"$2\"",);
        let ran = Command::new("sh")
            .arg("-c")
            .arg(&script)
            .arg(mema_bin())
            .arg(shared("office1.pcd"))
            .arg(&out)
            .env("RUST_BACKTRACE", "1")
            .output()
            .expect("sh runs");
        let stderr = String::from_utf8_lossy(&ran.stderr);
        match ran.status.code() {
            Some(0) => {
                successes += 1;
                assert!(out.exists(), "{limit_kb} KB: exit 0 without a map");
            }
            Some(1) => {
                let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
                assert_eq!(lines.len(), 1, "{limit_kb} KB: not one line:\n{stderr}");
                let line = lines[0];
                assert!(
                    line.starts_with("mema: ")
                        && (line.contains("out of memory") || line.contains("worker threads")),
                    "{limit_kb} KB: {line}"
                );
                allocator_refusals += usize::from(line.contains("bytes per point"));
            }
            other => panic!("{limit_kb} KB: exit {other:?}:\n{stderr}"),
        }
        let _ = std::fs::remove_file(&out);
    }
    assert!(successes > 0, "no limit was enough to map");
    assert!(
        allocator_refusals > 0,
        "no limit ran out after reading (the allocator's one-line error)"
    );
}
