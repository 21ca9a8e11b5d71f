//! Writes the seed corpora of the link's fuzz targets (`uplink_decoder`, `downlink_decoder`,
//! `carrier`, `map_frames`) into DIR/TARGET/, from a tiny session between a host and the
//! board's loop (`mema_firmware_sim::fuzz_checks::link_seeds`). `scripts/fuzz.sh` runs it.
//! Usage: cargo run --example link_seeds -- DIR

use std::path::PathBuf;

fn main() -> std::io::Result<()> {
    let Some(dir) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: link_seeds DIR");
        std::process::exit(2);
    };
    for (target, name, bytes) in mema_firmware_sim::fuzz_checks::link_seeds() {
        let at = dir.join(target);
        std::fs::create_dir_all(&at)?;
        std::fs::write(at.join(name), bytes)?;
    }
    Ok(())
}
