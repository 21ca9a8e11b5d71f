//! The command line's usage errors (this file also makes `cargo test` build the binary that the
//! workspace tests in `tests/tests/firmware.rs` drive).

use std::process::Command;

fn sim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_mema-firmware-sim"))
        .args(args)
        .output()
        .expect("runs")
}

#[test]
fn usage_errors_exit_2_with_one_message() {
    for args in [
        &[][..],
        &["fly"],
        &["run"],
        &["run", "x", "-k", "0"],
        &["run", "x", "--bogus", "1"],
    ] {
        let out = sim(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.starts_with("mema-firmware-sim: "), "{err}");
    }
    let out = sim(&["run", "/nonexistent/capture.bin"]);
    assert_eq!(out.status.code(), Some(1));
}

#[test]
fn budget_reports_the_three_capacities() {
    let out = sim(&["budget", "--json"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for k in ["\"k\":150", "\"k\":400", "\"k\":1000"] {
        assert!(text.contains(k), "{text}");
    }
}
