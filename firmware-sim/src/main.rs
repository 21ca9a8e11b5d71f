//! `mema-firmware-sim`: the core run as firmware runs it, with a report.
//!
//! ```text
//! mema-firmware-sim run CAPTURE [-k 150] [--seed 0] [-o MAP] [--chunk-seed 0] [--max-chunk 256]
//!                   [--snapshot-every 16] [--fault-seed 0] [--noise PPM] [--overrun PPM]
//!                   [--truncate PPM] [--reset PPM] [--accepted FILE] [--json]
//! mema-firmware-sim budget [--image ELF] [--qemu-report FILE] [--board ELF] [--board-run FILE] [--json]     (feature reference)
//! mema-firmware-sim reference [CLOUD ...] [-k 150] [--seed 0] [--json]     (feature reference)
//! ```
//! Exit status: 0 success, 1 a failed run or check, 2 bad usage.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match cli::dispatch(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mema-firmware-sim: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
