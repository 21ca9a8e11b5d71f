//! Any bytes from a device, fed to the host's assembler whole and in pieces: the same account
//! whatever the pieces, counts a plain model of the same bytes agrees with, and a map only of
//! the end frame's length and CRC that reads back.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema::link::fuzz_checks::map_frames;

fuzz_target!(|data: &[u8]| {
    if let Err(violation) = map_frames(data) {
        panic!("{violation:?}");
    }
});
