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
    // On a thread with a large stack: the firmware's state holds 4,096 working clusters (1.2
    // MB), and an unoptimised build moves copies of its parts through the stack.
    let run = std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(move || cli::dispatch(&args).map_err(|e| (e.to_string(), e.exit_code())));
    match run.map(|h| h.join()) {
        Ok(Ok(Ok(()))) => ExitCode::SUCCESS,
        Ok(Ok(Err((message, code)))) => {
            eprintln!("mema-firmware-sim: {message}");
            ExitCode::from(code)
        }
        Ok(Err(_)) => ExitCode::from(1),
        Err(e) => {
            eprintln!("mema-firmware-sim: cannot start the simulator's thread: {e}");
            ExitCode::from(1)
        }
    }
}
