//! Any bytes, read as a point cloud under the name the first byte picks (KITTI `.bin` is told by
//! its name): never a panic, and either a one-line error naming the file or a cloud of finite
//! points whose counts agree.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema::io::read::fuzz_checks::cloud_bytes;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    if let Err(violation) = cloud_bytes(pick, bytes) {
        panic!("{violation:?}");
    }
});
