//! Decoder fuzzing in the test suite: 10^6 random and mutated byte sequences, in random chunks.
//! No panic, every frame the decoder hands out is valid and counted, and every block comes out
//! as a plain split-decode-check of the same bytes says it should. (A coverage-guided
//! cargo-fuzz target would need nightly; this seeded loop runs on stable in CI, in seconds.)

use mema_core::link::cobs::{cobs_decode_in_place, cobs_encode};
use mema_core::link::wire::{
    Decoded, Decoder, Frame, FrameError, FrameRepr, MAX_FRAME_LEN, MAX_RAW_LEN,
};

struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// A valid wire stream of a few frames to mutate.
fn seed_stream(rng: &mut XorShift) -> Vec<u8> {
    let mut out = vec![0u8];
    for seq in 0..1 + rng.below(4) {
        let points: Vec<[i32; 3]> = (0..rng.below(20))
            .map(|_| [rng.next() as i32, (rng.next() % 3) as i32, 0])
            .collect();
        let repr = FrameRepr {
            sequence: seq as u32,
            end_of_stream: false,
            unit_exponent: -3,
            points: &points,
        };
        let mut raw = [0u8; MAX_RAW_LEN];
        let len = repr.emit(&mut raw).expect("fits");
        let mut enc = [0u8; 2 * MAX_RAW_LEN];
        let n = cobs_encode(&raw[..len], &mut enc).expect("fits");
        out.extend_from_slice(&enc[..n]);
        out.push(0);
    }
    out
}

fn mutate(rng: &mut XorShift, bytes: &mut Vec<u8>) {
    for _ in 0..rng.below(6) {
        if bytes.is_empty() {
            bytes.push(rng.next() as u8);
        }
        let i = rng.below(bytes.len());
        match rng.below(6) {
            0 => bytes[i] ^= 1 << rng.below(8),
            1 => {
                bytes.remove(i);
            }
            2 => bytes.insert(i, rng.next() as u8),
            3 => bytes.truncate(i),
            4 => {
                // Splice a copy of a random stretch (duplicated bytes or frames).
                let j = rng.below(bytes.len());
                let (a, b) = (i.min(j), i.max(j));
                let copy = bytes[a..b].to_vec();
                let at = rng.below(bytes.len());
                bytes.splice(at..at, copy);
            }
            _ => bytes[i] = 0,
        }
    }
}

/// What the decoder made of one block.
#[derive(Debug, PartialEq)]
enum Outcome {
    Frame(Vec<u8>),
    /// A valid frame that repeats the last one (the decoder hands out no bytes).
    Repeat,
    Error(FrameError),
}

/// The decoder's blocks the plain way, as an independent reference: the bytes between
/// delimiters, refused past the largest frame, decoded by `cobs_decode_in_place`, checked by
/// `Frame::new_checked`.
#[derive(Default)]
struct Reference {
    block: Vec<u8>,
    outcomes: Vec<Outcome>,
}

impl Reference {
    fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if b != 0 {
                self.block.push(b);
                continue;
            }
            let mut block = std::mem::take(&mut self.block);
            if block.len() > MAX_FRAME_LEN {
                self.outcomes.push(Outcome::Error(FrameError::Oversized));
            } else if !block.is_empty() {
                self.outcomes.push(match cobs_decode_in_place(&mut block) {
                    None => Outcome::Error(FrameError::BadCobs),
                    Some(n) => match Frame::new_checked(&block[..n]) {
                        Ok(_) => Outcome::Frame(block[..n].to_vec()),
                        Err(e) => Outcome::Error(e),
                    },
                });
            }
        }
    }

    /// Checks the decoder's outcomes against this one's, and forgets both.
    fn check(&mut self, decoded: &mut Vec<Outcome>) {
        assert_eq!(decoded.len(), self.outcomes.len(), "{decoded:?}");
        for (got, want) in decoded.iter().zip(&self.outcomes) {
            match got {
                Outcome::Repeat => assert!(matches!(want, Outcome::Frame(_)), "{want:?}"),
                Outcome::Error(FrameError::Duplicate { .. }) => unreachable!(),
                _ => assert_eq!(got, want),
            }
        }
        decoded.clear();
        self.outcomes.clear();
    }
}

#[test]
fn a_million_hostile_sequences() {
    let mut rng = XorShift(0x00C0_FFEE_D00D_F00D);
    let mut decoder = Decoder::new();
    let mut accepted = 0u64;
    let mut reference = Reference::default();
    let mut decoded = Vec::new();
    let sequences = 1_000_000;
    for i in 0..sequences {
        let bytes = if i % 2 == 0 {
            // Random bytes with a random share of zeros (delimiters).
            // Now and then a block around the largest frame's length, to reach the limit.
            let long = rng.below(200) == 0;
            let zero_every = if long { 5000 } else { 1 + rng.below(300) };
            let len = if long {
                MAX_FRAME_LEN - 100 + rng.below(200)
            } else {
                rng.below(400)
            };
            (0..len)
                .map(|_| {
                    if rng.below(zero_every) == 0 {
                        0
                    } else {
                        rng.next() as u8
                    }
                })
                .collect()
        } else {
            let mut s = seed_stream(&mut rng);
            mutate(&mut rng, &mut s);
            s
        };
        // A fresh decoder now and then; otherwise state carries across sequences, as on a link.
        if rng.below(16) == 0 {
            decoder = Decoder::new();
            reference = Reference::default();
        }
        reference.feed(&bytes);
        let before = *decoder.stats();
        let mut at = 0;
        while at < bytes.len() {
            let n = (1 + rng.below(64)).min(bytes.len() - at);
            let mut window = &bytes[at..at + n];
            loop {
                match decoder.feed(window) {
                    Decoded::Consumed => break,
                    Decoded::Rejected { error, remaining } => {
                        decoded.push(match error {
                            FrameError::Duplicate { .. } => Outcome::Repeat,
                            e => Outcome::Error(e),
                        });
                        window = remaining;
                    }
                    Decoded::Frame { frame, remaining } => {
                        let raw: &[u8] = frame.into_inner();
                        decoded.push(Outcome::Frame(raw.to_vec()));
                        assert!(
                            Frame::new_checked(raw).is_ok(),
                            "handed out an invalid frame"
                        );
                        accepted += 1;
                        window = remaining;
                    }
                }
            }
            at += n;
        }
        reference.check(&mut decoded);
        let after = decoder.stats();
        assert_eq!(after.bytes - before.bytes, bytes.len() as u64);
        let delimiters = bytes.iter().filter(|&&b| b == 0).count() as u64;
        let outcomes = (after.accepted + after.rejected + after.duplicates)
            - (before.accepted + before.rejected + before.duplicates);
        assert!(
            outcomes <= delimiters,
            "{outcomes} outcomes from {delimiters} delimiters"
        );
    }
    assert!(
        accepted > 1000,
        "mutations should leave many frames intact: {accepted}"
    );
    eprintln!("decoder fuzz: {sequences} sequences, {accepted} frames accepted");
}

/// Blocks at the largest frame's length and one byte either side, as the reference splits them.
#[test]
fn blocks_at_the_length_limit() {
    let mut rng = XorShift(0x5EED);
    for len in MAX_FRAME_LEN - 1..=MAX_FRAME_LEN + 1 {
        for _ in 0..50 {
            let mut bytes: Vec<u8> = (0..len).map(|_| 1 + rng.below(255) as u8).collect();
            bytes.push(0);
            let (mut decoder, mut reference) = (Decoder::new(), Reference::default());
            reference.feed(&bytes);
            let mut decoded = Vec::new();
            let mut window = &bytes[..];
            loop {
                match decoder.feed(window) {
                    Decoded::Consumed => break,
                    Decoded::Rejected { error, remaining } => {
                        decoded.push(Outcome::Error(error));
                        window = remaining;
                    }
                    Decoded::Frame { frame, remaining } => {
                        decoded.push(Outcome::Frame(frame.into_inner().to_vec()));
                        window = remaining;
                    }
                }
            }
            reference.check(&mut decoded);
        }
    }
}
