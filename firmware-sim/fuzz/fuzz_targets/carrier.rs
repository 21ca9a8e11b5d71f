//! Any bytes on the board's line, fed through its line ring in pieces into a small map ring
//! drained a few bytes at a time: the carrier passes on exactly the in-session, in-turn carry
//! frames' bytes, hands on exactly the requests, and reports what a plain model of the same
//! bytes says.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema_firmware_sim::fuzz_checks::carrier;

fuzz_target!(|data: &[u8]| {
    if let Err(violation) = carrier(data) {
        panic!("{violation:?}");
    }
});
