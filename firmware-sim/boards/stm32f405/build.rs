//! Puts memory.x where cortex-m-rt's link.x looks for it: the whole flash from 0x08000000, or
//! (feature `crazyflie`) the flash above a bootloader's first 16 KiB, or (feature `qemu`) the
//! part as QEMU models it, with no core-coupled RAM.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory = if env::var_os("CARGO_FEATURE_CRAZYFLIE").is_some() {
        "memory/crazyflie.x"
    } else if env::var_os("CARGO_FEATURE_QEMU").is_some() {
        "memory/qemu.x"
    } else {
        "memory/whole-flash.x"
    };
    fs::copy(memory, out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    // Not in the package's root: the linker looks in its working directory first.
    println!("cargo:rerun-if-changed=memory");
}
