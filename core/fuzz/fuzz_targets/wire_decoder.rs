//! Any bytes on the link, fed whole and in pieces of a size the input picks: the same frames,
//! and counters that agree with them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mema_core::fuzz_checks::wire_stream;

fuzz_target!(|data: &[u8]| {
    let Some((&piece, bytes)) = data.split_first() else {
        return;
    };
    if let Err(violation) = wire_stream(bytes, usize::from(piece) + 1) {
        panic!("{violation:?}");
    }
});
