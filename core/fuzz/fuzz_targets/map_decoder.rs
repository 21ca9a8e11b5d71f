//! Any bytes, as they are and with the CRC made right: the `.mema` decoder accepts only sound
//! maps, and what it accepts re-encodes to the same entities.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema_core::fuzz_checks::map_file;

fuzz_target!(|data: &[u8]| {
    if let Err(violation) = map_file(data) {
        panic!("{violation:?}");
    }
});
