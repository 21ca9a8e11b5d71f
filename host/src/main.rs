//! `mema`: errors are printed once as `mema: <context>: <cause>` (no backtrace, whatever
//! RUST_BACKTRACE says). Exit status: 0 success, 1 bad input or I/O failure, 2 bad usage,
//! 3 a stream that ended before its end-of-stream frame (its map is still written).

use clap::Parser;
use mema::cli::{Cli, Command, UsageError};
use mema::link::commands::LinkLost;
use std::process::ExitCode;

// Counts live and peak heap bytes, which `mema bench` reports (see `mema::heap`).
#[global_allocator]
static HEAP: mema::heap::Counting = mema::heap::Counting;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Map(a) => mema::commands::map(a),
        Command::Eval(a) => mema::analysis::eval::eval(a),
        Command::Info(a) => mema::commands::info(a),
        Command::Demo(a) => mema::commands::demo(a),
        Command::Ablation(a) => mema::commands::ablation(a),
        Command::StreamBench(a) => mema::commands::stream_bench(a),
        Command::Stream(a) => mema::link::commands::stream(a),
        Command::Record(a) => mema::link::commands::record(a),
        Command::Replay(a) => mema::link::commands::replay(a),
        Command::ScannerSim(a) => mema::link::commands::scanner_sim(a),
        Command::Query(a) => mema::query::query(a),
        Command::Transform(a) => mema::query::transform(a),
        Command::QueryBench(a) => mema::query::query_bench(a),
        Command::Draw(a) => mema::toolbox::draw(a),
        Command::Export(a) => mema::toolbox::export(a),
        Command::Completions(a) => mema::toolbox::completions(a),
        Command::Man => mema::toolbox::man(),
        Command::Bench(a) => mema::bench::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mema: {e:#}");
            if e.downcast_ref::<UsageError>().is_some() {
                ExitCode::from(2)
            } else if e.downcast_ref::<LinkLost>().is_some() {
                ExitCode::from(3)
            } else {
                ExitCode::from(1)
            }
        }
    }
}
