use super::*;
use crate::link::framing::decode_block;
use crate::test_support::{OrFail, TestResult, damaged_blocks_are_refused, hex};

/// The examples' session and boot (PROTOCOL.md).
const TO: Address = Address {
    session: 0x5E55_1011,
    boot: 7,
};

/// Decodes a whole COBS block.
fn decode_whole(block: &mut [u8]) -> Result<(Address, UpFrame<'_>), LinkError> {
    decode(decode_block(block)?)
}

/// PROTOCOL.md's host-to-device examples, computed independently by
/// `scripts/protocol_examples.py` (Python's `struct`, `zlib.crc32` and a COBS written from its
/// definition): mema emits exactly them and reads them back.
#[test]
fn protocol_examples() -> TestResult {
    let stream_start = [0x00, 0x04, 0x02, 0x02, 0x08, 0x01, 0x01, 0x01];
    let any_boot = Address {
        session: TO.session,
        boot: 0,
    };
    let examples = [
        (
            any_boot,
            UpFrame::Request(Request::Start { first: 0 }),
            "07 84 04 11 10 55 5e 01 01 01 01 01 01 01 01 01 01 01 05 74 77 39 ed 00",
        ),
        (
            TO,
            UpFrame::Carry {
                sequence: 0,
                bytes: &stream_start,
            },
            "02 84 06 11 10 55 5e 07 01 01 01 01 01 01 01 0c 04 02 02 08 01 01 01 c4 ec b5 c2 00",
        ),
        (
            TO,
            UpFrame::Request(Request::Resend { first: 7, count: 3 }),
            "08 84 01 11 10 55 5e 07 01 01 01 01 01 01 02 07 01 01 02 03 05 aa e3 84 a9 00",
        ),
        (
            TO,
            UpFrame::Request(Request::ResendEnd),
            "08 84 02 11 10 55 5e 07 01 01 01 01 01 01 05 dc 17 1b fd 00",
        ),
        (
            TO,
            UpFrame::Request(Request::Query {
                number: 77,
                ray: true,
                point: [1.5, -2.0, 0.25],
                direction: [0.0, 0.6, -0.8],
            }),
            "08 84 03 11 10 55 5e 07 01 01 02 4d 01 01 02 01 01 03 c0 3f 01 01 02 c0 01 03 80 3e \
             01 01 01 0d 9a 99 19 3f cd cc 4c bf 96 c2 b6 8f 00",
        ),
    ];
    for (to, frame, wire) in examples {
        let mut want = [0u8; MAX_UP_FRAME_LEN];
        let n = hex(wire, &mut want)?;
        let mut got = [0u8; MAX_UP_FRAME_LEN];
        let m = encode(to, &frame, &mut got).or_fail("encodes")?;
        assert_eq!(got.get(..m), want.get(..n), "{frame:?}");
        let block = want.get_mut(..n - 1).or_fail("block")?;
        assert_eq!(decode_whole(block).or_fail("decodes")?, (to, frame));
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
    let n = encode(TO, &frame, &mut sent).or_fail("encodes")?;
    assert!(n <= MAX_UP_FRAME_LEN);
    let block_len = n - 1;
    let mut block = sent;
    let back = decode_whole(block.get_mut(..block_len).or_fail("block")?).or_fail("decodes")?;
    assert_eq!(back, (TO, frame));
    damaged_blocks_are_refused(sent, block_len, |b| decode_whole(b).is_ok())?;
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let empty = UpFrame::Carry {
        sequence: 0,
        bytes: &[],
    };
    assert_eq!(encode(TO, &empty, &mut out), Err(LinkError::BufferTooSmall));
    // A start without a session is no request.
    let none = Address::default();
    let n = encode(
        none,
        &UpFrame::Request(Request::Start { first: 0 }),
        &mut out,
    )
    .or_fail("encodes")?;
    assert_eq!(
        decode_whole(out.get_mut(..n - 1).or_fail("block")?),
        Err(LinkError::Value)
    );
    Ok(())
}

/// A request whose number is not `0` where PROTOCOL.md says it is (resend, resend the end,
/// start) is refused: read as the request, it would re-encode to other bytes, so two frames
/// would mean one request (the `uplink_decoder` fuzz target's first finding: a resend-the-end
/// numbered 9).
#[test]
fn a_request_numbered_where_none_is_is_refused() -> TestResult {
    for request in [
        Request::Resend { first: 7, count: 3 },
        Request::ResendEnd,
        Request::Start { first: 5 },
    ] {
        let mut wire = [0u8; MAX_UP_FRAME_LEN];
        let n = encode(TO, &UpFrame::Request(request), &mut wire).or_fail("encodes")?;
        let block = wire.get_mut(..n - 1).or_fail("block")?;
        let raw_len = decode_block(block).or_fail("a block")?.len();
        // The number field set to 9, the CRC made right again.
        let mut raw = [0u8; MAX_UP_RAW_LEN];
        let raw = raw.get_mut(..raw_len).or_fail("room")?;
        raw.copy_from_slice(block.get(..raw_len).or_fail("raw")?);
        assert_eq!(decode(raw).map(|(_, f)| f), Ok(UpFrame::Request(request)));
        raw[10] = 9;
        let crc = crate::link::crc32::crc32(raw.get(..raw_len - CRC_LEN).or_fail("body")?);
        raw.get_mut(raw_len - CRC_LEN..)
            .or_fail("crc")?
            .copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(raw), Err(LinkError::Value), "{request:?}");
    }
    Ok(())
}
