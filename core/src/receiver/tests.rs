use super::*;
use crate::test_support::{OrFail, TestResult};
use crate::wire::{FrameRepr, MAX_RAW_LEN, cobs_encode};

/// Appends frame `sequence` (COBS and delimiter) to `out` at `at`; returns the new end.
fn push(
    out: &mut [u8],
    at: usize,
    sequence: u32,
    end_of_stream: bool,
    unit_exponent: i8,
    points: &[[i32; 3]],
) -> Result<usize, &'static str> {
    let repr = FrameRepr {
        sequence,
        end_of_stream,
        unit_exponent,
        points,
    };
    let mut raw = [0u8; MAX_RAW_LEN];
    let len = repr.emit(&mut raw).or_fail("emit")?;
    let room = out.get_mut(at..).or_fail("room")?;
    let n = cobs_encode(raw.get(..len).or_fail("raw")?, room).or_fail("encode")?;
    *out.get_mut(at + n).or_fail("room")? = 0;
    Ok(at + n + 1)
}

/// Feeds `input` in chunks of `chunk`, the way a caller loops; returns the points mapped (as
/// a sum of their coordinates and a count, enough to tell two streams apart) and the number
/// of frames mapped.
fn receive(r: &mut Receiver, input: &[u8], chunk: usize) -> ([f64; 3], usize, usize) {
    let mut sum = [0.0f64; 3];
    let (mut points, mut frames) = (0, 0);
    for piece in input.chunks(chunk.max(1)) {
        let mut window = piece;
        loop {
            match r.feed(window) {
                Received::Consumed => break,
                Received::Skipped { remaining, .. } => window = remaining,
                Received::Points {
                    frame,
                    placement,
                    remaining,
                } => {
                    frames += 1;
                    for p in placement.points(&frame) {
                        for (s, v) in sum.iter_mut().zip(p.to_array()) {
                            *s += v as f64;
                        }
                        points += 1;
                    }
                    window = remaining;
                }
            }
        }
    }
    (sum, points, frames)
}

/// Frames after the end-of-stream frame were mapped, and how many depended on the chunking
/// (100 points with 1-byte chunks, 200 with 4 KiB, as the caller stopped after its chunk):
/// now they are counted and never mapped, whatever the chunking.
#[test]
fn frames_after_the_end_are_counted_not_mapped() -> TestResult {
    let mut wire = [0u8; 4096];
    let mut at = 1;
    for seq in 0..6u32 {
        let pts = [[seq as i32, 2, 3], [4, seq as i32 * 10, 6]];
        // Frame 2 ends the stream; 3..6 follow it on the same line.
        at = push(&mut wire, at, seq, seq == 2, -3, &pts)?;
    }
    let input = wire.get(..at).or_fail("wire")?;
    let mut expected = None;
    for chunk in [1, 2, 5, 13, 64, at] {
        let mut r = Receiver::new();
        let got = receive(&mut r, input, chunk);
        assert_eq!((got.1, got.2), (6, 3), "chunk {chunk}: frames 0..=2 only");
        assert!(r.ended());
        assert_eq!(r.stats().after_end, 3, "chunk {chunk}");
        assert_eq!(r.decoder_stats().accepted, 6);
        match expected {
            None => expected = Some(got),
            Some(e) => assert_eq!(got, e, "chunk {chunk}"),
        }
    }
    Ok(())
}

/// Near 0 the origin is 0 and a point reaches the mapper as `(v * 10^e) as f32`, the bits it
/// had before the receiver kept an origin; far out, the origin is the first point's 1,024 m
/// cell and the points keep their spacing.
#[test]
fn the_origin_keeps_millimetres_anywhere_on_the_link() -> TestResult {
    let near = [[1234, -5678, 91_011], [-511_999, 0, 7]];
    let mut wire = [0u8; 512];
    let at = push(&mut wire, 1, 0, true, -3, &near)?;
    let mut r = Receiver::new();
    let Received::Points {
        frame, placement, ..
    } = r.feed(wire.get(..at).or_fail("wire")?)
    else {
        return Err("a frame of points");
    };
    assert_eq!(placement.origin().map(f64::to_bits), [0.0f64.to_bits(); 3]);
    for (i, q) in near.iter().enumerate() {
        let want = q.map(|v| (v as f64 * libm::pow(10.0, -3.0)) as f32);
        // Bits, so a -0 would show.
        assert_eq!(
            placement.point(&frame, i).or_fail("point")?.to_array(),
            want
        );
    }

    // 2,000 km out in millimetres, 1 mm apart: f32 around 0 would resolve only 0.125 m.
    let base = 2_000_000_000i32;
    let far = [[base, -base, base / 2], [base + 1, -base + 1, base / 2 + 1]];
    let at = push(&mut wire, 1, 0, false, -3, &far)?;
    let mut r = Receiver::new();
    let Received::Points {
        frame, placement, ..
    } = r.feed(wire.get(..at).or_fail("wire")?)
    else {
        return Err("a frame of points");
    };
    let o = placement.origin();
    assert!(o.iter().all(|v| v % ORIGIN_CELL == 0.0));
    assert_eq!(o, [1_999_872.0, -1_999_872.0, 1_000_448.0]);
    let a = placement.point(&frame, 0).or_fail("first")?.to_array();
    let b = placement.point(&frame, 1).or_fail("second")?.to_array();
    for j in 0..3 {
        assert!((b[j] - a[j] - 0.001).abs() < 1e-5, "axis {j}: {a:?} {b:?}");
        // Within the cell: the world point is origin + local to f32 precision there.
        let world = far[0][j] as f64 * 1e-3;
        assert!((o[j] + a[j] as f64 - world).abs() < 1e-4);
    }
    // A second frame keeps the first frame's origin.
    let at = push(&mut wire, 1, 1, true, -3, &near)?;
    let Received::Points { placement, .. } = r.feed(wire.get(..at).or_fail("wire")?) else {
        return Err("a frame of points");
    };
    assert_eq!(placement.origin(), o);
    Ok(())
}
