//! Any bytes as device-to-host frames, each block as it is and with its CRC made right: what
//! the downlink decoder accepts is within the protocol's bounds and re-encodes to its raw
//! frame.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema_core::fuzz_checks::downlink_frames;

fuzz_target!(|data: &[u8]| {
    if let Err(violation) = downlink_frames(data) {
        panic!("{violation:?}");
    }
});
