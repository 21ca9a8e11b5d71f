//! The board's receiver of the host's frames ([`Carrier`]) on any bytes, and the seeds of the
//! link's fuzz targets: the property `firmware-sim/fuzz`'s `carrier` target checks under
//! cargo-fuzz (`scripts/fuzz.sh`) and the test suite checks on mutations of the same seeds
//! (`tests/tests/fuzzing.rs`), one definition for both.
//!
//! The property: the carrier, fed through a line [`Ring`] in pieces and passing on into a
//! small map ring drained a few bytes at a time (so it holds carried bytes while the map ring
//! is full), passes on exactly the stream bytes of the carry frames that are of its session and
//! boot and in turn, in order; hands on exactly the requests; and reports the number it
//! expects and the frames it refused. What "exactly" is comes from a model written apart from
//! it: the bytes split at every `0x00`, each block COBS-decoded in place by the plain decoder
//! and read by `uplink::decode`, then the protocol's rules (PROTOCOL.md, "Host to device").

use mema_core::fuzz_checks::{crcs_made_right, plain_blocks};
use mema_core::link::cobs::{cobs_decode_in_place, cobs_encode};
use mema_core::link::downlink::{self, DeviceLayout, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd};
use mema_core::link::frame::Address;
use mema_core::link::uplink::{self, MAX_CARRIED, MAX_UP_FRAME_LEN, UpFrame};
use mema_core::link::wire::{FrameRepr, MAX_FRAME_LEN, MAX_RAW_LEN};
use mema_core::map::Layout;

use mema_firmware::device::{Boot, Device, NoClock, Out, Poll};
use mema_firmware::{
    Carrier, Firmware, IMAGE_REACH, RX_CAPACITY, Request, Ring, SHELLS, model_params,
};

/// The seeds' device: 12 working clusters and 4 frozen entities, so its whole downlink is a
/// couple of kilobytes (the board's 700 entity frames alone would make the assembler's seeds
/// over 45 KB).
const SEED_WORKING: usize = 12;
const SEED_FROZEN: usize = 4;
const SEED_BUCKETS: usize = 16;

/// The carrier target's input: a header, then the line's bytes. The header: the piece size
/// the line's ring is fed in (`1 + 16 b`), the bytes drained from the map ring at a time
/// (`1 + b`), whether every block's CRC is made right first (`b & 1`: so a mutation reaches
/// the frames' numbers and addresses), the carrier's session and boot (u32 each), and the
/// number of the carry frame it expects first (u32), little-endian.
pub const CARRIER_HEADER: usize = 3 + 4 + 4 + 4;

/// The map ring the carrier passes on into: smaller than a carry frame, so it fills and the
/// carrier holds the rest.
const MAP_RING: usize = 200;

/// A property the carrier broke.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CarrierViolation {
    /// It passed on other bytes than the in-turn carry frames' (lengths: what it passed, what
    /// the model says).
    Passed { got: usize, expected: usize },
    /// It handed on other requests than the model's.
    Requests { got: String, expected: String },
    /// Its report (bytes taken, number expected next, frames refused) is not the model's.
    Report { got: String, expected: String },
    /// It stopped taking the line's bytes with room to pass them on.
    Stuck,
}

/// What the carrier did with an input, when it kept its promises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CarrierOutcome {
    /// Stream bytes passed on, requests handed on, frames refused.
    pub passed: usize,
    pub requests: usize,
    pub refused: u32,
}

/// The carrier target's input for the line's `bytes`: see [`CARRIER_HEADER`].
pub fn carrier_input(
    address: Address,
    first: u32,
    (piece, drain, crcs_right): (u8, u8, bool),
    bytes: &[u8],
) -> Vec<u8> {
    let mut data = vec![piece, drain, u8::from(crcs_right)];
    for v in [address.session, address.boot, first] {
        data.extend_from_slice(&v.to_le_bytes());
    }
    data.extend_from_slice(bytes);
    data
}

/// What the carrier must do with the line's bytes, by the model.
#[derive(Debug, Default)]
struct Expected {
    passed: Vec<u8>,
    requests: Vec<(Request, u32)>,
    next: u32,
    refused: u32,
}

/// The model: every block ended by a delimiter (what follows the last delimiter is not yet a
/// frame), decoded by the plain decoder, then the protocol's rules for a device in boot
/// `address.boot` and session `address.session` expecting carry frame `first`.
fn model(address: Address, first: u32, bytes: &[u8]) -> Expected {
    let mut x = Expected {
        next: first,
        ..Expected::default()
    };
    // The carrier keeps one longest frame's block: a longer one is refused whole.
    plain_blocks(bytes, MAX_UP_FRAME_LEN, |_, raw| {
        let Some(raw) = raw else {
            x.refused += 1;
            return;
        };
        match uplink::decode(raw) {
            Err(_) => x.refused += 1,
            // A start request is for the device to act on, whatever session it is in.
            Ok((from, UpFrame::Request(start @ Request::Start { .. }))) => {
                x.requests.push((start, from.session))
            }
            Ok((from, _)) if from != address || address.session == 0 => x.refused += 1,
            Ok((from, UpFrame::Request(request))) => x.requests.push((request, from.session)),
            Ok((_, UpFrame::Carry { sequence, bytes })) => {
                let ahead = sequence.wrapping_sub(x.next);
                if ahead == 0 {
                    x.next = x.next.wrapping_add(1);
                    x.passed.extend_from_slice(bytes);
                } else if ahead <= u32::MAX / 2 {
                    x.refused += 1;
                }
                // Behind: a repeat of one taken, dropped without counting.
            }
        }
    });
    x
}

/// The carrier on a fuzz input ([`CARRIER_HEADER`], then the line's bytes): what it passes on,
/// hands on and reports is the model's.
pub fn carrier(data: &[u8]) -> Result<CarrierOutcome, CarrierViolation> {
    let Some((header, bytes)) = data.split_first_chunk::<CARRIER_HEADER>() else {
        return Ok(CarrierOutcome::default());
    };
    let u32_at = |at: usize| {
        u32::from_le_bytes([header[at], header[at + 1], header[at + 2], header[at + 3]])
    };
    let piece = 1 + 16 * usize::from(header[0]);
    let drain = 1 + usize::from(header[1]);
    let address = Address {
        session: u32_at(3),
        boot: u32_at(7),
    };
    let first = u32_at(11);
    let fixed;
    let bytes = if header[2] & 1 == 1 {
        let mut made = Vec::with_capacity(bytes.len() + 16);
        crcs_made_right(bytes, |piece| made.extend_from_slice(piece));
        fixed = made;
        &fixed[..]
    } else {
        bytes
    };
    let line = Ring::<RX_CAPACITY>::new();
    let map = Ring::<MAP_RING>::new();
    let mut c = Carrier::new(address, first);
    let (mut passed, mut requests) = (Vec::new(), Vec::new());
    let mut at = 0;
    // Every pass moves at least one byte through one of the three stages (the line's ring,
    // the carrier, the map ring), each of which sees every byte once.
    let mut passes = 0;
    while at < bytes.len() || !line.is_empty() || c.holding() || !map.is_empty() {
        passes += 1;
        if passes > 3 * bytes.len() + 8 {
            return Err(CarrierViolation::Stuck);
        }
        at += line.push(&bytes[at..(at + piece).min(bytes.len())]);
        while let Some(r) = c.pump(&line, &map) {
            requests.push(r);
        }
        map.consume_front(|front| {
            let n = front.len().min(drain);
            passed.extend_from_slice(&front[..n]);
            n
        });
    }
    let x = model(address, first, bytes);
    if passed != x.passed {
        return Err(CarrierViolation::Passed {
            got: passed.len(),
            expected: x.passed.len(),
        });
    }
    let (got, expected) = (format!("{requests:?}"), format!("{:?}", x.requests));
    if got != expected {
        return Err(CarrierViolation::Requests { got, expected });
    }
    // The line has gone quiet with every byte taken and the stream has ended: a report is due,
    // and says it all (mid-stream a quiet line is not reported: PROGRESS_EVERY bytes are).
    c.close();
    let report = c.report_due(&line).map(|r| (r.taken, r.next, r.refused));
    let want = (!bytes.is_empty()).then_some((bytes.len() as u32, x.next, x.refused));
    if report != want {
        return Err(CarrierViolation::Report {
            got: format!("{report:?}"),
            expected: format!("{want:?}"),
        });
    }
    Ok(CarrierOutcome {
        passed: passed.len(),
        requests: requests.len(),
        refused: x.refused,
    })
}

/// The session the seeds are of (PROTOCOL.md's examples' number).
pub const SEED_SESSION: u32 = 0x5E55_1011;

/// A tiny session between a host and the board's loop ([`Device`]), as the line carried it:
/// the start request, the carry frames of a stream of 120 points in 3 frames and the requests
/// after its end (entities again, the end again, a nearest-surface query and a ray), and every
/// byte the device sent back.
#[derive(Clone, Debug)]
pub struct TinySession {
    /// The device's boot and session once the session began, and its first carry frame.
    pub address: Address,
    pub first_carry: u32,
    /// The host's frames: the start request, the carry frames, the requests.
    pub uplink: Vec<u8>,
    /// The carry frames alone, and the requests alone.
    pub carried: Vec<Vec<u8>>,
    pub requests: Vec<Vec<u8>>,
    /// Everything the device sent, its boot's session frame first.
    pub downlink: Vec<u8>,
    /// Points and points frames in the stream carried.
    pub points: u32,
    pub frames: u32,
}

fn up(to: Address, frame: &UpFrame<'_>) -> Vec<u8> {
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let n = uplink::encode(to, frame, &mut out).unwrap_or(0);
    out[..n].to_vec()
}

/// The points stream: a leading delimiter and three version 1 frames of 40 points on two
/// small spheres and a plane, in millimetres, the last flagged end of stream.
fn points_stream() -> Vec<u8> {
    let mut out = vec![0u8];
    for f in 0..3u32 {
        let points: Vec<[i32; 3]> = (0..40)
            .map(|i| {
                let t = (f * 40 + i) as f64 * 0.37;
                let (c, r) = match i % 3 {
                    0 => ([0.0, 0.0, 0.0], 400.0),
                    1 => ([2000.0, 500.0, 0.0], 250.0),
                    _ => ([0.0, 0.0, -1500.0], 0.0),
                };
                let p = if r > 0.0 {
                    [
                        c[0] + r * t.cos() * (0.7 * t).sin(),
                        c[1] + r * t.sin() * (0.7 * t).sin(),
                        c[2] + r * (0.7 * t).cos(),
                    ]
                } else {
                    [(t * 97.0) % 3000.0, (t * 61.0) % 3000.0, c[2]]
                };
                p.map(|v| v as i32)
            })
            .collect();
        let repr = FrameRepr {
            sequence: f,
            end_of_stream: f == 2,
            unit_exponent: -3,
            points: &points,
        };
        let mut raw = [0u8; MAX_RAW_LEN];
        let mut wire = [0u8; MAX_FRAME_LEN];
        let len = repr.emit(&mut raw).unwrap_or(0);
        let n = cobs_encode(&raw[..len], &mut wire).unwrap_or(0);
        out.extend_from_slice(&wire[..n]);
        out.push(0);
    }
    out
}

/// Runs one boot of the device on `phases` of line bytes (each phase once the device is idle
/// after the last), appending what it sends to `downlink`; returns the reset a start request
/// asked for, if one did.
fn run_boot(boot: Boot, phases: &[&[u8]], downlink: &mut Vec<u8>) -> Option<(u32, u32)> {
    let (line, map) = (Ring::<RX_CAPACITY>::new(), Ring::<RX_CAPACITY>::new());
    let params = model_params(0, SEED_WORKING, SEED_FROZEN, SHELLS);
    let mut firmware: Box<Firmware<SEED_WORKING, SEED_BUCKETS, SEED_FROZEN, _>> =
        Box::new(Firmware::with_ring(params, IMAGE_REACH, &map));
    let layout = DeviceLayout {
        capacity: (SEED_WORKING + SEED_FROZEN) as u32,
        working: SEED_WORKING as u32,
        model: 1,
    };
    let mut device = Device::new(&mut firmware, (&line, &map), boot, layout);
    let mut delimiters = 0u32;
    let mut send = |_: Out, b: &[u8]| downlink.extend_from_slice(b);
    for phase in phases {
        let mut rest = *phase;
        loop {
            let n = line.push(rest);
            delimiters =
                delimiters.wrapping_add(rest[..n].iter().filter(|&&b| b == 0).count() as u32);
            rest = &rest[n..];
            while device.awake(delimiters) {
                if let Poll::Reset { session, first } =
                    device.poll(delimiters, &mut NoClock, &mut send)
                {
                    return Some((session, first));
                }
            }
            if rest.is_empty() {
                break;
            }
        }
    }
    None
}

/// The tiny session, its carry frames numbered from `first_carry`.
pub fn tiny_session(first_carry: u32) -> TinySession {
    let stream = points_stream();
    let mut downlink = Vec::new();
    let start = up(
        Address {
            session: SEED_SESSION,
            boot: 0,
        },
        &UpFrame::Request(Request::Start { first: first_carry }),
    );
    // Boot 1, in no session: announces itself; the start request resets it into the session.
    let booted = Boot {
        address: Address {
            session: 0,
            boot: 1,
        },
        ..Boot::default()
    };
    let (session, first) = run_boot(booted, &[&start], &mut downlink).unwrap_or_default();
    let address = Address { session, boot: 2 };
    let carried: Vec<Vec<u8>> = stream
        .chunks(MAX_CARRIED)
        .zip(0u32..)
        .map(|(bytes, i)| {
            let sequence = first.wrapping_add(i);
            up(address, &UpFrame::Carry { sequence, bytes })
        })
        .collect();
    let requests: Vec<Vec<u8>> = [
        Request::Resend { first: 0, count: 3 },
        Request::ResendEnd,
        Request::Query {
            number: 77,
            ray: false,
            point: [0.1, 0.2, 0.3],
            direction: [0.0; 3],
        },
        Request::Query {
            number: 78,
            ray: true,
            point: [0.0, 0.0, 3.0],
            direction: [0.0, 0.0, -1.0],
        },
    ]
    .iter()
    .map(|r| up(address, &UpFrame::Request(*r)))
    .collect();
    let (carry_bytes, request_bytes) = (carried.concat(), requests.concat());
    let started = Boot {
        address,
        first_carry: first,
        first_sequence: 0,
    };
    run_boot(started, &[&carry_bytes, &request_bytes], &mut downlink);
    TinySession {
        address,
        first_carry: first,
        uplink: [start, carry_bytes, request_bytes].concat(),
        carried,
        requests,
        downlink,
        points: 120,
        frames: 3,
    }
}

/// A downlink frame (its delimiter included) as it is, or if an end frame, saying the
/// oriented layout.
fn as_oriented(frame: &[u8]) -> Vec<u8> {
    let mut raw = frame[..frame.len() - 1].to_vec();
    let Some(n) = cobs_decode_in_place(&mut raw) else {
        return frame.to_vec();
    };
    let Ok((from, sequence, DownFrame::End(end))) = downlink::decode(&raw[..n]) else {
        return frame.to_vec();
    };
    let end = DownFrame::End(MapEnd {
        layout: Layout::Oriented,
        ..end
    });
    let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
    let n = downlink::encode(from, sequence, &end, &mut wire).unwrap_or(0);
    wire[..n].to_vec()
}

/// The blocks of a stream with their delimiters: one frame each.
fn frames_of(bytes: &[u8]) -> Vec<Vec<u8>> {
    bytes
        .split_inclusive(|&b| b == 0)
        .filter(|f| f.len() > 1)
        .map(<[u8]>::to_vec)
        .collect()
}

/// The seeds of the link's four fuzz targets, as (target, name, input), from two tiny sessions
/// (carry frames numbered from 0, and from just before their wrap): every frame alone and each
/// direction's whole stream for the decoders; the carrier's line (whole, cut short, with a
/// damaged, an early and a repeated frame) under a few piece and drain sizes; the device's
/// bytes for the assembler, with the stream's counts or none, and with an entity frame lost.
/// The assembler's header is `mema::link::fuzz_checks::FRAMES_HEADER`'s layout (the host is
/// not a dependency of this crate; the test suite checks these seeds reach its map).
pub fn link_seeds() -> Vec<(&'static str, String, Vec<u8>)> {
    let mut seeds = Vec::new();
    for (tag, first) in [("s0", 0), ("wrap", u32::MAX - 1)] {
        let s = tiny_session(first);
        for (target, bytes) in [
            ("uplink_decoder", &s.uplink),
            ("downlink_decoder", &s.downlink),
        ] {
            seeds.push((target, format!("{tag}-whole"), bytes.clone()));
            // A frame of each length (each kind; carry frames of two lengths) is enough.
            let mut lengths = Vec::new();
            for (i, frame) in frames_of(bytes).into_iter().enumerate() {
                if !lengths.contains(&frame.len()) {
                    lengths.push(frame.len());
                    seeds.push((target, format!("{tag}-frame{i}"), frame));
                }
            }
        }
        let mut faulty = Vec::new();
        let mut damaged = s.carried[1].clone();
        damaged[20] ^= 0x44;
        for f in [
            &s.carried[0],
            &damaged,
            &s.carried[2],
            &s.carried[1],
            &s.carried[0],
        ] {
            faulty.extend_from_slice(f);
        }
        faulty.extend_from_slice(&s.requests[0]);
        let short = [&s.carried[..3].concat()[..], &s.requests[1]].concat();
        for (name, sizes, line) in [
            ("whole", (15, 63, true), &s.uplink),
            ("short", (0, 0, false), &short),
            ("faulty", (255, 7, false), &faulty),
        ] {
            let input = carrier_input(s.address, s.first_carry, sizes, line);
            seeds.push(("carrier", format!("{tag}-{name}"), input));
        }
        let frames = frames_of(&s.downlink);
        // A frame lost midway (an entity: they are most of the frames).
        let mut lost = frames.clone();
        lost.remove(frames.len() / 2);
        let lost = lost.concat();
        // The end saying the oriented layout (its length and CRC then not the map's: the
        // assembler's check makes them right), so mutations reach full-precision records.
        let oriented: Vec<u8> = frames.iter().flat_map(|f| as_oriented(f)).collect();
        for (name, piece, crcs_right, expected, bytes) in [
            ("whole", 63u8, true, (s.points, s.frames), &s.downlink),
            ("unexpected", 0, false, (0, 0), &s.downlink),
            ("lost", 200, true, (s.points, s.frames), &lost),
            ("oriented", 31, true, (s.points, s.frames), &oriented),
        ] {
            let mut input = vec![piece, u8::from(crcs_right)];
            for v in [s.address.session, expected.0, expected.1] {
                input.extend_from_slice(&v.to_le_bytes());
            }
            input.extend_from_slice(bytes);
            seeds.push(("map_frames", format!("{tag}-{name}"), input));
        }
    }
    seeds
}
