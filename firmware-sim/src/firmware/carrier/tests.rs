use super::*;
use mema_core::uplink::{MAX_CARRIED, encode};

/// A stream of `len` bytes with zeros in it, as a points stream has delimiters.
fn stream(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 7 % 13) as u8).collect()
}

/// The stream's carry frames on the wire, one `Vec` each.
fn carried(stream: &[u8]) -> Vec<Vec<u8>> {
    stream
        .chunks(MAX_CARRIED)
        .enumerate()
        .map(|(i, bytes)| {
            let mut out = [0u8; MAX_UP_FRAME_LEN];
            let frame = UpFrame::Carry {
                sequence: i as u32,
                bytes,
            };
            let n = encode(&frame, &mut out).expect("encodes");
            out[..n].to_vec()
        })
        .collect()
}

/// Delivers `bytes` through the carrier into a map ring drained into `out` as it fills.
fn deliver(c: &mut Carrier, bytes: &[u8], out: &mut Vec<u8>, requests: &mut Vec<Request>) {
    let line: Ring<4096> = Ring::new();
    let map: Ring<512> = Ring::new();
    for piece in bytes.chunks(1000) {
        assert_eq!(line.push(piece), piece.len());
        loop {
            c.pump(&line, &map, |r| requests.push(r));
            map.consume_front(|front| {
                out.extend_from_slice(front);
                front.len()
            });
            map.consume_front(|front| {
                out.extend_from_slice(front);
                front.len()
            });
            if line.is_empty() && !c.holding() {
                break;
            }
        }
    }
}

/// Carry frames taken in turn pass on exactly the stream; a damaged frame, one ahead of its
/// turn and a repeat are kept out, counted and reported, and the frames sent again from the
/// number expected complete the stream.
#[test]
fn only_the_next_frame_passes_on() {
    let s = stream(10 * MAX_CARRIED + 17);
    let frames = carried(&s);
    let mut c = Carrier::new();
    let (mut out, mut requests) = (Vec::new(), Vec::new());
    // Frames 0..3 whole, 3 with a flipped byte, 4 and 5 (ahead of 3), 2 again (a repeat).
    let mut line = Vec::new();
    for f in &frames[..3] {
        line.extend_from_slice(f);
    }
    let mut damaged = frames[3].clone();
    damaged[40] ^= 0x10;
    line.extend_from_slice(&damaged);
    line.extend_from_slice(&frames[4]);
    line.extend_from_slice(&frames[5]);
    line.extend_from_slice(&frames[2]);
    deliver(&mut c, &line, &mut out, &mut requests);
    assert_eq!(out, s[..3 * MAX_CARRIED]);
    let probe: Ring<8> = Ring::new();
    let report = c.report_due(&probe).expect("refusals are reported at once");
    assert_eq!((report.next, report.refused), (3, 3));
    // Sent again from 3: the rest arrives, and the stream is whole.
    let mut again = Vec::new();
    for f in &frames[3..] {
        again.extend_from_slice(f);
    }
    deliver(&mut c, &again, &mut out, &mut requests);
    assert_eq!(out, s);
    assert!(requests.is_empty());
}

/// Requests reach the caller between the frames around them; after `close`, carry frames are
/// still acknowledged but pass nothing on.
#[test]
fn requests_come_through_and_a_closed_carrier_passes_nothing() {
    let s = stream(3 * MAX_CARRIED);
    let frames = carried(&s);
    let mut c = Carrier::new();
    let (mut out, mut requests) = (Vec::new(), Vec::new());
    let mut line = frames[0].clone();
    let mut ask = [0u8; MAX_UP_FRAME_LEN];
    let n = encode(
        &UpFrame::Request(Request::Resend { first: 9, count: 2 }),
        &mut ask,
    )
    .expect("encodes");
    line.extend_from_slice(&ask[..n]);
    line.extend_from_slice(&frames[1]);
    let n = encode(&UpFrame::Request(Request::ResendEnd), &mut ask).expect("encodes");
    line.extend_from_slice(&ask[..n]);
    deliver(&mut c, &line, &mut out, &mut requests);
    assert_eq!(out, s[..2 * MAX_CARRIED]);
    assert_eq!(
        requests,
        [Request::Resend { first: 9, count: 2 }, Request::ResendEnd]
    );
    c.close();
    deliver(&mut c, &frames[2], &mut out, &mut requests);
    assert_eq!(out.len(), 2 * MAX_CARRIED);
    let probe: Ring<8> = Ring::new();
    assert_eq!(c.report_due(&probe).map(|r| r.next), None);
    assert_eq!(c.next, 3);
}
