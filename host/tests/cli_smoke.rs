//! Keeps `cargo test` building the `mema` binary that the workspace tests in `tests/` drive.

use std::process::Command;

#[test]
fn help_lists_every_command() {
    let out = Command::new(env!("CARGO_BIN_EXE_mema"))
        .arg("--help")
        .output()
        .expect("mema runs");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for command in ["map", "eval", "info", "demo", "ablation"] {
        assert!(
            text.contains(command),
            "{command} missing from --help:\n{text}"
        );
    }
}
