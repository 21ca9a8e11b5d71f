//! Fault injection on the wire (foundation of the firmware issue's injector): bit flips, dropped
//! bytes, truncated, duplicated frames and line noise. Every corrupted frame is refused, every
//! clean frame is used once, and the map equals the map of the clean frames alone.

use crate::util::{Dir, MemaCommand, shared};
use mema::io::load_cloud;
use mema::link::frames::{POINTS_PER_FRAME, push_frame, quantise};
use mema::link::stream::{Capacity, Link};

/// A seeded xorshift (also the downlink's fault injector, `device.rs`).
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Fault {
    Clean,
    BitFlip,
    DropByte,
    Truncate,
    Duplicate,
    NoiseBefore,
}

/// One frame as it goes on the wire (COBS body + delimiter).
fn framed(sequence: u32, last: bool, points: &[[i32; 3]]) -> Vec<u8> {
    let mut out = Vec::new();
    push_frame(&mut out, sequence, last, points).expect("frame");
    out
}

/// Applies `fault` to one framed frame. Faults corrupt the body only, keeping the delimiter, so
/// which frames are clean is known exactly.
fn inject(rng: &mut Rng, fault: Fault, frame: &[u8], out: &mut Vec<u8>) -> bool {
    let (body, delimiter) = frame.split_at(frame.len() - 1);
    match fault {
        Fault::Clean => out.extend_from_slice(frame),
        Fault::Duplicate => {
            out.extend_from_slice(frame);
            out.extend_from_slice(frame);
        }
        Fault::NoiseBefore => {
            for _ in 0..1 + rng.below(40) {
                out.push(1 + rng.below(255) as u8);
            }
            out.push(0);
            out.extend_from_slice(frame);
        }
        Fault::BitFlip => {
            let mut b = body.to_vec();
            let i = rng.below(b.len());
            b[i] ^= 1 << rng.below(8);
            out.extend_from_slice(&b);
            out.extend_from_slice(delimiter);
            return false;
        }
        Fault::DropByte => {
            let mut b = body.to_vec();
            b.remove(rng.below(b.len()));
            out.extend_from_slice(&b);
            out.extend_from_slice(delimiter);
            return false;
        }
        Fault::Truncate => {
            out.extend_from_slice(&body[..rng.below(body.len())]);
            out.extend_from_slice(delimiter);
            return false;
        }
    }
    true
}

#[test]
fn corrupted_frames_are_refused_and_the_map_is_that_of_the_clean_frames() {
    let dir = Dir::new("faults");
    let cloud = load_cloud(&shared("bun_zipper.ply")).expect("bunny");
    let wire: Vec<[i32; 3]> = cloud
        .points
        .iter()
        .map(|p| quantise(*p).expect("fits"))
        .collect();
    let chunks: Vec<&[[i32; 3]]> = wire.chunks(POINTS_PER_FRAME).collect();
    let faults = [
        Fault::BitFlip,
        Fault::DropByte,
        Fault::Truncate,
        Fault::Duplicate,
        Fault::NoiseBefore,
    ];
    for (round, rate) in [(1u64, 5usize), (2, 20), (3, 50)] {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ round);
        let mut corrupted = vec![0u8];
        let mut clean = vec![0u8];
        let (mut bad, mut duplicated) = (0u64, 0u64);
        for (seq, pts) in chunks.iter().enumerate() {
            // The last frame stays clean: it carries end of stream.
            let last = seq + 1 == chunks.len();
            let frame = framed(seq as u32, last, pts);
            let fault = if !last && rng.below(100) < rate {
                faults[rng.below(faults.len())]
            } else {
                Fault::Clean
            };
            if inject(&mut rng, fault, &frame, &mut corrupted) {
                clean.extend_from_slice(&frame);
                duplicated += u64::from(fault == Fault::Duplicate);
            } else {
                bad += 1;
            }
        }
        let mut expected = Link::new(Capacity::all_working(100), 0, Default::default(), 0.0);
        expected.feed(&clean);
        let expected_map = expected.finish().to_mema().expect("encode");

        // Random chunk sizes, as a UART delivers.
        let mut link = Link::new(Capacity::all_working(100), 0, Default::default(), 0.0);
        let mut at = 0;
        while at < corrupted.len() {
            let n = (1 + rng.below(700)).min(corrupted.len() - at);
            link.feed(&corrupted[at..at + n]);
            at += n;
        }
        let s = *link.stats();
        assert_eq!(
            s.accepted,
            chunks.len() as u64 - bad,
            "round {round}: every clean frame is used"
        );
        assert_eq!(
            s.lost, bad,
            "round {round}: each refused frame is a gap in the sequence"
        );
        assert!(
            s.rejected >= bad,
            "round {round}: {} rejected for {bad} corrupted frames",
            s.rejected
        );
        assert_eq!(
            s.duplicates, duplicated,
            "round {round}: repeats are used once"
        );
        assert!(link.end_of_stream());
        assert_eq!(
            link.finish().to_mema().expect("encode"),
            expected_map,
            "round {round}"
        );
        eprintln!(
            "round {round}: {bad} corrupted, {duplicated} duplicated of {} frames; rejected {}",
            chunks.len(),
            s.rejected
        );

        // The real binary, replaying the corrupted bytes, writes the same map.
        let capture = dir.write(&format!("faulty-{round}.bin"), &corrupted);
        let out = dir.join(&format!("faulty-{round}.mema"));
        MemaCommand::new(&dir)
            .arg("replay")
            .arg(&capture)
            .args(["-k", "100", "--model", "paper", "--chunk-bytes", "97", "-o"])
            .arg(&out)
            .run()
            .assert_ok();
        assert_eq!(std::fs::read(&out).expect("map"), expected_map);
    }
}

#[test]
fn faults_anywhere_never_panic_and_accept_only_clean_frames() {
    // Faults that also hit delimiters: which frames survive is not known in advance, but every
    // accepted frame must be one the scanner sent, unaltered.
    let cloud = load_cloud(&shared("car6.pcd")).expect("car6");
    let wire: Vec<[i32; 3]> = cloud
        .points
        .iter()
        .map(|p| quantise(*p).expect("fits"))
        .collect();
    let mut stream = vec![0u8];
    for (seq, pts) in wire.chunks(POINTS_PER_FRAME).enumerate() {
        push_frame(&mut stream, seq as u32, false, pts).expect("frame");
    }
    let mut rng = Rng(42);
    for trial in 0..200 {
        let mut bytes = stream.clone();
        for _ in 0..1 + rng.below(30) {
            let i = rng.below(bytes.len());
            match rng.below(3) {
                0 => bytes[i] ^= 1 << rng.below(8),
                1 => {
                    bytes.remove(i);
                }
                _ => bytes.insert(i, rng.next() as u8),
            }
        }
        let mut decoder = mema_core::link::wire::Decoder::new();
        let mut window: &[u8] = &bytes;
        loop {
            match decoder.feed(window) {
                mema_core::link::wire::Decoded::Consumed => break,
                mema_core::link::wire::Decoded::Rejected { remaining, .. } => window = remaining,
                mema_core::link::wire::Decoded::Frame { frame, remaining } => {
                    let seq = frame.sequence() as usize;
                    let sent = &wire
                        [seq * POINTS_PER_FRAME..((seq + 1) * POINTS_PER_FRAME).min(wire.len())];
                    let got: Vec<[i32; 3]> = (0..frame.point_count() as usize)
                        .filter_map(|i| frame.point(i))
                        .collect();
                    assert_eq!(got, sent, "trial {trial}: frame {seq} accepted altered");
                    window = remaining;
                }
            }
        }
    }
}
