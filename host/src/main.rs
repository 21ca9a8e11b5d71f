//! `mema`: errors are printed once as `mema: <context>: <cause>` (no backtrace, whatever
//! RUST_BACKTRACE says). Exit status: 0 success, 1 bad input or I/O failure, 2 bad usage,
//! 3 a stream that ended before its end-of-stream frame (its map is still written).

mod cli;

use clap::Parser;
use std::process::ExitCode;

// Counts live and peak heap bytes, which `mema bench` reports (see `mema::heap`).
#[global_allocator]
static HEAP: mema::heap::Counting = mema::heap::Counting;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match cli::run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mema: {}", cli::errors::message(&e));
            ExitCode::from(cli::errors::exit_status(&e))
        }
    }
}
