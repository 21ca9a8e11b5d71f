use super::*;
use crate::test_support::{OrFail, TestResult, damaged_blocks_are_refused, hex};

/// PROTOCOL.md's host-to-device examples, computed independently (Python's `struct`,
/// `zlib.crc32` and a COBS written from its definition): mema emits exactly them and reads
/// them back.
#[test]
fn protocol_examples() -> TestResult {
    let stream_start = [0x00, 0x04, 0x02, 0x02, 0x08, 0x01, 0x01, 0x01];
    let examples = [
        (
            UpFrame::Carry {
                sequence: 0,
                bytes: &stream_start,
            },
            "02 82 01 01 01 01 01 0c 04 02 02 08 01 01 01 ff c7 8b da 00",
        ),
        (
            UpFrame::Request(Request::Resend { first: 7, count: 3 }),
            "03 82 01 01 01 01 02 07 01 01 02 03 04 ab 8b 8f 01 00",
        ),
        (
            UpFrame::Request(Request::ResendEnd),
            "03 82 02 01 01 01 05 10 47 7a 98 00",
        ),
    ];
    for (frame, wire) in examples {
        let mut want = [0u8; MAX_UP_FRAME_LEN];
        let n = hex(wire, &mut want)?;
        let mut got = [0u8; MAX_UP_FRAME_LEN];
        let m = encode(&frame, &mut got).or_fail("encodes")?;
        assert_eq!(got.get(..m), want.get(..n), "{frame:?}");
        let block = want.get_mut(..n - 1).or_fail("block")?;
        assert_eq!(decode(block).or_fail("decodes")?, frame);
    }
    Ok(())
}

/// The longest carry frame fits the stated wire length, and every flipped byte or cut of it
/// is refused, never read as other stream bytes.
#[test]
fn a_damaged_carry_frame_is_refused() -> TestResult {
    let mut bytes = [0u8; MAX_CARRIED];
    for (i, b) in bytes.iter_mut().enumerate() {
        *b = (i * 37 % 251) as u8;
    }
    let frame = UpFrame::Carry {
        sequence: 0x0102_0304,
        bytes: &bytes,
    };
    let mut sent = [0u8; MAX_UP_FRAME_LEN];
    let n = encode(&frame, &mut sent).or_fail("encodes")?;
    assert!(n <= MAX_UP_FRAME_LEN);
    let block_len = n - 1;
    let mut block = sent;
    let back = decode(block.get_mut(..block_len).or_fail("block")?).or_fail("decodes")?;
    assert_eq!(back, frame);
    damaged_blocks_are_refused(sent, block_len, |b| decode(b).is_ok())?;
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let empty = UpFrame::Carry {
        sequence: 0,
        bytes: &[],
    };
    assert_eq!(encode(&empty, &mut out), Err(UplinkError::BufferTooSmall));
    let query = UpFrame::Request(Request::Query {
        number: 77,
        ray: true,
        point: [1.5, -2.0, 1e6],
        direction: [0.0, 0.6, -0.8],
    });
    let n = encode(&query, &mut out).or_fail("a query encodes")?;
    let back = decode(out.get_mut(..n - 1).or_fail("block")?).or_fail("decodes")?;
    assert_eq!(back, query);
    Ok(())
}
