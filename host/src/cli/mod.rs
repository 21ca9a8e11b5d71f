//! The `mema` command line: clap arguments ([`args`]), one handler per subcommand
//! ([`commands`]: checks the arguments, calls the library, prints), and how errors read and
//! exit ([`errors`]). Only `main.rs` uses it, and nothing in the library uses it.

pub mod args;
pub mod commands;
pub mod errors;

pub use args::{Cli, Command};

/// Runs the subcommand `cli` holds.
pub fn run(cli: &Cli) -> anyhow::Result<()> {
    use commands::{
        bench, capture, demo, demo_moving, device, eval, info, map, query, serial, toolbox,
    };
    match &cli.command {
        Command::Map(a) => map::map(a),
        Command::Eval(a) => eval::eval(a),
        Command::Info(a) => info::info(a),
        Command::Demo(a) if a.moving => demo_moving::demo_moving(a),
        Command::Demo(a) => demo::demo(a),
        Command::Ablation(a) => bench::ablation(a),
        Command::StreamBench(a) => bench::stream_bench(a),
        Command::Stream(a) => serial::stream(a),
        Command::Record(a) => capture::record(a),
        Command::Replay(a) => serial::replay(a),
        Command::Device(a) => device::device(a),
        Command::ScannerSim(a) => capture::scanner_sim(a),
        Command::Query(a) => query::query(a),
        Command::Transform(a) => query::transform(a),
        Command::QueryBench(a) => query::query_bench(a),
        Command::Draw(a) => toolbox::draw(a),
        Command::Export(a) => toolbox::export(a),
        Command::Completions(a) => toolbox::completions(a),
        Command::Man(a) => toolbox::man(a),
        Command::Bench(a) => bench::bench(a),
    }
}
