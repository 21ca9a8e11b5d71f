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
    // A bug must still read as one line, not a backtrace (RUST_BACKTRACE is often set).
    std::panic::set_hook(Box::new(|info| {
        let payload = info.payload();
        let what = payload
            .downcast_ref::<&str>()
            .copied()
            .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
            .unwrap_or("a panic");
        // std panics in a new thread (rayon's, or the query index's) whose signal stack cannot
        // be mapped: under a memory limit that is running out of memory, not a bug, and the
        // process must end with the one line and exit 1 it gives every other allocation failure.
        if what.starts_with("failed to allocate an alternative stack") {
            eprintln!("mema: out of memory: a new thread's signal stack could not be allocated");
            std::process::exit(1);
        }
        // println! to a reader that has gone (`mema info MAP | head -1`).
        if what.starts_with("failed printing to stdout") && what.contains("Broken pipe") {
            cli::errors::end_on_closed_stdout();
        }
        match info.location() {
            Some(at) => eprintln!("mema: internal error: {what} ({}:{})", at.file(), at.line()),
            None => eprintln!("mema: internal error: {what}"),
        }
    }));
    // The worker threads start here, where a limit on threads or memory is one line and exit
    // 1, rather than a panic in the first parallel step.
    if let Err(e) = rayon::ThreadPoolBuilder::new().build_global() {
        eprintln!("mema: cannot start the worker threads: {e}");
        return ExitCode::from(1);
    }
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return cli::errors::usage_failed(e),
    };
    match cli::run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mema: {}", cli::errors::message(&e));
            ExitCode::from(cli::errors::exit_status(&e))
        }
    }
}
