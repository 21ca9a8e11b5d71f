//! PROTOCOL.md's worked examples (issue 32): every frame type of both protocols has one, the
//! document shows exactly the bytes `scripts/protocol_examples.py` computes from the document
//! alone (Python's `struct`, `zlib.crc32` and a COBS written from its definition), and mema reads
//! each example and emits it again to the byte. The core's unit tests check the same bytes from
//! the encoder's side; this test ties them to the document and the script.

use std::path::Path;
use std::process::Command;

use mema_core::link::framing::{decode_block, frame_raw};
use mema_core::link::wire::{Content, Frame, FrameKind, FrameRepr, FrameReprV2};
use mema_core::link::{downlink, uplink};

/// One example: its raw frame and its bytes on the wire.
#[derive(Debug, PartialEq)]
pub(crate) struct Example {
    pub(crate) raw: Vec<u8>,
    wire: Vec<u8>,
}

fn bytes_of(hex: &str) -> Vec<u8> {
    hex.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("a hex byte"))
        .collect()
}

/// The `raw` and `wire` line pairs of a text, in order.
fn examples_in(text: &str) -> Vec<Example> {
    let mut examples = Vec::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        if let Some(raw) = line.strip_prefix("raw  ") {
            let wire = lines
                .next()
                .and_then(|l| l.strip_prefix("wire "))
                .expect("a `wire` line after every `raw` line");
            examples.push(Example {
                raw: bytes_of(raw),
                wire: bytes_of(wire),
            });
        }
    }
    examples
}

fn repository() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// The script's examples and their names.
fn script_examples() -> (Vec<String>, Vec<Example>) {
    let out = Command::new("python3")
        .arg("scripts/protocol_examples.py")
        .current_dir(repository())
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("text");
    let names = text
        .lines()
        .filter_map(|l| l.strip_prefix("# "))
        .map(String::from)
        .collect();
    (names, examples_in(&text))
}

pub(crate) fn document_examples() -> Vec<Example> {
    let text = std::fs::read_to_string(repository().join("PROTOCOL.md")).expect("PROTOCOL.md");
    examples_in(&text)
}

#[test]
fn protocol_md_shows_exactly_the_scripts_examples() {
    let (names, script) = script_examples();
    let document = document_examples();
    assert_eq!(names.len(), script.len());
    assert_eq!(
        document.len(),
        script.len(),
        "PROTOCOL.md and scripts/protocol_examples.py differ in their number of examples"
    );
    for ((name, doc), computed) in names.iter().zip(&document).zip(&script) {
        assert_eq!(
            doc, computed,
            "example `{name}`: PROTOCOL.md against the script"
        );
    }
}

/// Every frame type: the wire's version 1 points, version 2 points, pose and wide pose; the
/// device's kinds 0-6 and the host's 0-4.
#[test]
fn every_frame_type_has_an_example() {
    let (names, script) = script_examples();
    let mut wire_kinds = Vec::new();
    let mut down_kinds = Vec::new();
    let mut up_kinds = Vec::new();
    for (name, e) in names.iter().zip(&script) {
        match e.raw[0] {
            1 => wire_kinds.push("v1"),
            2 => wire_kinds.push(["points", "pose", "wide pose"][usize::from(e.raw[9])]),
            downlink::DOWNLINK_VERSION => down_kinds.push(e.raw[1]),
            uplink::UPLINK_VERSION => up_kinds.push(e.raw[1]),
            v => panic!("example `{name}`: version {v:#x}"),
        }
    }
    wire_kinds.sort();
    down_kinds.sort();
    down_kinds.dedup();
    up_kinds.sort();
    assert_eq!(wire_kinds, ["points", "pose", "v1", "wide pose"]);
    assert_eq!(down_kinds, [0, 1, 2, 3, 4, 5, 6]);
    assert_eq!(up_kinds, [0, 1, 2, 3, 4]);
}

/// mema reads each example (CRC, lengths, every field) and emits it again to the byte.
#[test]
fn mema_reads_and_emits_every_example_to_the_byte() {
    for (i, e) in document_examples().iter().enumerate() {
        let (delimiter, block) = e.wire.split_last().expect("not empty");
        assert_eq!(*delimiter, 0, "example {i}: the delimiter");
        let mut block = block.to_vec();
        let raw = decode_block(&mut block).expect("a COBS block with a good CRC");
        assert_eq!(raw, e.raw.as_slice(), "example {i}: COBS");
        let mut out = [0u8; 2048];
        let n = match e.raw[0] {
            downlink::DOWNLINK_VERSION => {
                let (from, sequence, frame) = downlink::decode(raw).expect("a device frame");
                downlink::encode(from, sequence, &frame, &mut out).expect("encodes")
            }
            uplink::UPLINK_VERSION => {
                let (to, frame) = uplink::decode(raw).expect("a host frame");
                uplink::encode(to, &frame, &mut out).expect("encodes")
            }
            _ => {
                let frame = Frame::new_checked(raw).expect("a rangefinder frame");
                let points: Vec<[i32; 3]> = frame.points_from(0).collect();
                let mut again = [0u8; 2048];
                let len = if frame.version() == 1 {
                    FrameRepr {
                        sequence: frame.sequence(),
                        end_of_stream: frame.end_of_stream(),
                        unit_exponent: frame.unit_exponent(),
                        points: &points,
                    }
                    .emit(&mut again)
                } else {
                    let content = match frame.kind().expect("a kind") {
                        FrameKind::Points => Content::Points {
                            pose: frame.pose_number(),
                            points: &points,
                        },
                        _ => Content::Pose {
                            number: frame.pose_number(),
                            pose: frame.pose().expect("a pose"),
                        },
                    };
                    FrameReprV2 {
                        sequence: frame.sequence(),
                        end_of_stream: frame.end_of_stream(),
                        session_start: frame.session_start(),
                        unit_exponent: frame.unit_exponent(),
                        content,
                    }
                    .emit(&mut again)
                }
                .expect("emits");
                frame_raw(&again[..len], &mut out).expect("frames")
            }
        };
        assert_eq!(&out[..n], e.wire.as_slice(), "example {i}: emitted again");
    }
}
