use super::*;
use mema_core::link::uplink::{MAX_CARRIED, encode};

/// The device's boot and session in these tests.
const HERE: Address = Address {
    session: 0xC0FF_EE01,
    boot: 3,
};

/// A stream of `len` bytes with zeros in it, as a points stream has delimiters.
fn stream(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 7 % 13) as u8).collect()
}

/// The stream's carry frames on the wire, one `Vec` each.
fn carried(stream: &[u8], to: Address) -> Vec<Vec<u8>> {
    carried_from(stream, to, 0)
}

/// The same, numbered from `first`.
fn carried_from(stream: &[u8], to: Address, first: u32) -> Vec<Vec<u8>> {
    stream
        .chunks(MAX_CARRIED)
        .enumerate()
        .map(|(i, bytes)| {
            let mut out = [0u8; MAX_UP_FRAME_LEN];
            let frame = UpFrame::Carry {
                sequence: first.wrapping_add(i as u32),
                bytes,
            };
            let n = encode(to, &frame, &mut out).expect("encodes");
            out[..n].to_vec()
        })
        .collect()
}

/// Delivers `bytes` through the carrier into a map ring drained into `out` as it fills.
fn deliver(c: &mut Carrier, bytes: &[u8], out: &mut Vec<u8>, requests: &mut Vec<(Request, u32)>) {
    let line: Ring<4096> = Ring::new();
    let map: Ring<512> = Ring::new();
    for piece in bytes.chunks(1000) {
        assert_eq!(line.push(piece), piece.len());
        loop {
            while let Some(r) = c.pump(&line, &map) {
                requests.push(r);
            }
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
    let frames = carried(&s, HERE);
    let mut c = Carrier::new(HERE, 0);
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
    let frames = carried(&s, HERE);
    let mut c = Carrier::new(HERE, 0);
    let (mut out, mut requests) = (Vec::new(), Vec::new());
    let mut line = frames[0].clone();
    let mut ask = [0u8; MAX_UP_FRAME_LEN];
    let n = encode(
        HERE,
        &UpFrame::Request(Request::Resend { first: 9, count: 2 }),
        &mut ask,
    )
    .expect("encodes");
    line.extend_from_slice(&ask[..n]);
    line.extend_from_slice(&frames[1]);
    let n = encode(HERE, &UpFrame::Request(Request::ResendEnd), &mut ask).expect("encodes");
    line.extend_from_slice(&ask[..n]);
    deliver(&mut c, &line, &mut out, &mut requests);
    assert_eq!(out, s[..2 * MAX_CARRIED]);
    assert_eq!(
        requests,
        [
            (Request::Resend { first: 9, count: 2 }, HERE.session),
            (Request::ResendEnd, HERE.session)
        ]
    );
    c.close();
    deliver(&mut c, &frames[2], &mut out, &mut requests);
    assert_eq!(out.len(), 2 * MAX_CARRIED);
    let probe: Ring<8> = Ring::new();
    assert_eq!(c.report_due(&probe).map(|r| r.next), None);
    assert_eq!(c.next, 3);
}

/// Frames of another session, or addressed to another boot, pass nothing on and are refused,
/// as everything is before a session has begun; a start request comes through with the session
/// it asks for, whatever the carrier is in.
#[test]
fn only_the_sessions_frames_for_this_boot_pass_on() {
    let s = stream(2 * MAX_CARRIED);
    let other_session = Address {
        session: HERE.session + 1,
        ..HERE
    };
    let other_boot = Address {
        boot: HERE.boot + 1,
        ..HERE
    };
    let probe: Ring<8> = Ring::new();
    for (carrier_in, sent_to) in [
        (HERE, other_session),
        (HERE, other_boot),
        (
            Address {
                session: 0,
                boot: HERE.boot,
            },
            Address {
                session: 0,
                boot: HERE.boot,
            },
        ),
    ] {
        let mut c = Carrier::new(carrier_in, 0);
        let (mut out, mut requests) = (Vec::new(), Vec::new());
        let mut line: Vec<u8> = carried(&s, sent_to).concat();
        let mut ask = [0u8; MAX_UP_FRAME_LEN];
        let n = encode(
            sent_to,
            &UpFrame::Request(Request::Resend { first: 0, count: 1 }),
            &mut ask,
        )
        .expect("encodes");
        line.extend_from_slice(&ask[..n]);
        deliver(&mut c, &line, &mut out, &mut requests);
        assert!(out.is_empty() && requests.is_empty(), "{sent_to:?}");
        let report = c.report_due(&probe).expect("refusals are reported");
        assert_eq!((report.next, report.refused), (0, 3), "{sent_to:?}");
        let start = Address {
            session: 77,
            boot: 0,
        };
        let n = encode(
            start,
            &UpFrame::Request(Request::Start { first: 9 }),
            &mut ask,
        )
        .expect("encodes");
        deliver(&mut c, &ask[..n], &mut out, &mut requests);
        assert_eq!(requests, [(Request::Start { first: 9 }, 77)]);
    }
}

/// Carry frames numbered across the wrap of their counter pass on in turn, and a frame from
/// before the wrap sent again after it is a repeat, not one ahead.
#[test]
fn carry_numbers_across_their_wrap() {
    let s = stream(8 * MAX_CARRIED + 5);
    let first = u32::MAX - 3;
    let frames = carried_from(&s, HERE, first);
    let mut c = Carrier::new(HERE, first);
    let (mut out, mut requests) = (Vec::new(), Vec::new());
    let mut line: Vec<u8> = frames.concat();
    line.extend_from_slice(&frames[1]);
    deliver(&mut c, &line, &mut out, &mut requests);
    assert_eq!(out, s);
    assert_eq!(c.next, first.wrapping_add(9));
    let probe: Ring<8> = Ring::new();
    let report = c.report_due(&probe).expect("the repeat is reported");
    assert_eq!((report.next, report.refused), (5, 0));
}
