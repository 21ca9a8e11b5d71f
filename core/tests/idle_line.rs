//! A line idling at zero, in a debug build: `firmware-sim/check.sh` runs this file at
//! opt-level 0 (`cargo test --profile dev`), where the decoder once recursed per idle `0x00`
//! and 512 zeros in one chunk overflowed a 256 KiB stack. (In the test profile, at opt-level
//! 3, the optimiser turned that recursion into a loop, so only a debug build shows it.)

use mema_core::link::cobs::cobs_encode;
use mema_core::link::wire::{Decoded, Decoder, FrameRepr, MAX_RAW_LEN};

#[test]
fn a_hundred_thousand_idle_zeros_in_one_chunk_on_a_small_stack() {
    let ran = std::thread::Builder::new()
        .stack_size(256 << 10)
        .spawn(|| {
            let mut input = vec![0u8; 100_000];
            let mut raw = [0u8; MAX_RAW_LEN];
            let len = FrameRepr {
                sequence: 3,
                end_of_stream: true,
                unit_exponent: -3,
                points: &[[1, 2, 3]],
            }
            .emit(&mut raw)
            .expect("emit");
            let mut wire = [0u8; 64];
            let n = cobs_encode(&raw[..len], &mut wire).expect("encode");
            input.extend_from_slice(&wire[..n]);
            input.push(0);
            let mut decoder = Decoder::new();
            let mut frames = Vec::new();
            let mut window: &[u8] = &input;
            loop {
                match decoder.feed(window) {
                    Decoded::Consumed => break,
                    Decoded::Rejected { remaining, .. } => window = remaining,
                    Decoded::Frame { frame, remaining } => {
                        frames.push(frame.sequence());
                        window = remaining;
                    }
                }
            }
            (frames, *decoder.stats(), input.len())
        })
        .expect("thread")
        .join();
    // An overflow aborts the test process rather than coming back here.
    let (frames, stats, len) = ran.expect("the decoder ran to the end on a 256 KiB stack");
    assert_eq!(frames, vec![3]);
    assert_eq!((stats.accepted, stats.rejected), (1, 0));
    assert_eq!(stats.bytes, len as u64);
}
