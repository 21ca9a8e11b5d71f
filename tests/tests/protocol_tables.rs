//! PROTOCOL.md's field tables against the code (issue 32): in every `| offset | size |` table
//! each field starts where the one before it ends (or, an alternative by kind, where that one
//! starts), so one digit changed in an offset or a size breaks the chain; each table's end is
//! the code's header length or the length its paragraph gives (`**Entity** (kind 0, 45
//! bytes)`), and that length and kind are those of the document's worked example of the frame,
//! which mema reads and emits again to the byte (protocol_doc.rs).

use mema_core::link::downlink::DOWNLINK_VERSION;
use mema_core::link::frame;
use mema_core::link::uplink::{MAX_CARRIED, UPLINK_VERSION};
use mema_core::link::wire::{
    CRC_LEN, HEADER_LEN, HEADER_LEN_V1, POINT_LEN, POSE_LEN, WIDE_POSE_LEN,
};

use crate::guides::repository;
use crate::protocol_doc::document_examples;

/// A length linear in a frame's count `n`: `a + b n`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Linear(usize, usize);

impl Linear {
    fn plus(self, other: Linear) -> Linear {
        Linear(self.0 + other.0, self.1 + other.1)
    }
}

/// `14`, `12 n`, `n`, `10 + 12 n`, `14 + n`, `n, 1..=240` (the range aside).
fn linear(cell: &str) -> Linear {
    let cell = cell.split(',').next().expect("a cell").trim();
    let mut out = Linear(0, 0);
    for term in cell.split('+').map(str::trim) {
        match term.strip_suffix('n').map(str::trim) {
            Some("") => out.1 += 1,
            Some(b) => out.1 += b.parse::<usize>().expect("a coefficient"),
            None => out.0 += term.parse::<usize>().expect("a number"),
        }
    }
    out
}

/// A frame's payload as its paragraph states it, `**Entity** (kind 0, 45 bytes)`: the line,
/// the frame's version by its section (`## Device to host`, `## Host to device`), the kind, and
/// the length as written (`45`, `1 to 240`, `no payload`).
#[derive(Clone)]
struct Stated {
    line: usize,
    version: u8,
    kind: u8,
    bytes: String,
}

/// A field table: the line it starts on, the payload stated just before it (none for a
/// header), and its (offset, size, field) cells.
struct Table {
    line: usize,
    stated: Option<Stated>,
    rows: Vec<[String; 3]>,
}

fn read(text: &str) -> (Vec<Stated>, Vec<Table>) {
    let (mut stated, mut tables, mut version, mut last) = (Vec::new(), Vec::new(), 0, None);
    let lines: Vec<&str> = text.lines().collect();
    for (i, line) in lines.iter().enumerate() {
        if let Some(title) = line.strip_prefix("## ") {
            version = match title {
                "Device to host" => DOWNLINK_VERSION,
                "Host to device" => UPLINK_VERSION,
                _ => 0,
            };
            last = None;
        }
        if let Some(at) = line.find("** (kind ") {
            let rest = &line[at + "** (kind ".len()..];
            let (kind, rest) = rest.split_once(", ").expect("kind K, N bytes");
            let bytes = rest.split([')', ':']).next().expect("N bytes");
            let s = Stated {
                line: i + 1,
                version,
                kind: kind.parse().expect("a kind"),
                bytes: bytes.trim_end_matches(" bytes").to_string(),
            };
            stated.push(s.clone());
            last = Some(s);
        }
        if line.starts_with("| offset | size |") {
            let rows = lines[i + 2..]
                .iter()
                .take_while(|l| l.starts_with('|'))
                .map(|row| {
                    let cells: Vec<&str> =
                        row.trim_matches('|').split('|').map(str::trim).collect();
                    [0, 1, 2].map(|j| cells[j].to_string())
                })
                .collect();
            tables.push(Table {
                line: i + 1,
                stated: last.take(),
                rows,
            });
        }
    }
    (stated, tables)
}

/// Where the table's fields end (the CRC aside), checking that each starts where the one
/// before it ends or, an alternative, where it starts; and the CRC's size.
fn end_of(table: &Table) -> (Linear, Option<usize>) {
    let (mut end, mut start, mut crc) = (Linear(0, 0), Linear(0, 0), None);
    for [offset, size, _] in &table.rows {
        let size_n = linear(size);
        if let Some(back) = offset.strip_prefix("end - ") {
            crc = Some(linear(back).0);
            assert_eq!(
                size_n.0,
                crc.unwrap(),
                "PROTOCOL.md:{}: the CRC",
                table.line
            );
            continue;
        }
        let at = linear(offset);
        if at == end {
            start = at;
        } else if at != start {
            panic!(
                "PROTOCOL.md:{}: `{offset}` follows neither the field before it (which ends at \
                 {end:?}) nor its start",
                table.line
            );
        }
        if size == "4" && table.rows.last().is_some_and(|r| r[0] == *offset) && at.1 > 0 {
            // `14 + n | 4 | CRC-32`: the CRC after a payload of any length.
            crc = Some(4);
            continue;
        }
        end = at.plus(size_n);
    }
    (end, crc)
}

/// The payload of the document's example of a frame `version`/`kind`.
fn example_payload(version: u8, kind: u8, line: usize) -> usize {
    let example = document_examples()
        .into_iter()
        .find(|e| e.raw[0] == version && e.raw[1] == kind)
        .unwrap_or_else(|| panic!("PROTOCOL.md:{line}: no example of kind {kind}"));
    example.raw.len() - frame::HEADER_LEN - CRC_LEN
}

#[test]
fn every_frames_stated_length_is_its_examples() {
    let text = std::fs::read_to_string(repository().join("PROTOCOL.md")).expect("PROTOCOL.md");
    let (stated, _) = read(&text);
    assert_eq!(
        stated.len(),
        12,
        "the device's seven frames and the host's five"
    );
    for s in stated {
        let payload = example_payload(s.version, s.kind, s.line);
        match s.bytes.split_once(" to ") {
            // A carry frame: any length from 1 to MAX_CARRIED.
            Some((least, most)) => {
                assert_eq!((least, most), ("1", MAX_CARRIED.to_string().as_str()));
                assert!((1..=MAX_CARRIED).contains(&payload));
            }
            None if s.bytes == "no payload" => assert_eq!(payload, 0),
            None => assert_eq!(
                s.bytes,
                payload.to_string(),
                "PROTOCOL.md:{}: kind {}'s length against its example's",
                s.line,
                s.kind
            ),
        }
    }
}

#[test]
fn every_field_table_adds_up_to_its_frame() {
    let text = std::fs::read_to_string(repository().join("PROTOCOL.md")).expect("PROTOCOL.md");
    let (_, tables) = read(&text);
    let mut headers = Vec::new();
    for table in &tables {
        let (end, crc) = end_of(table);
        if let Some(crc) = crc {
            assert_eq!(crc, CRC_LEN, "PROTOCOL.md:{}: the CRC's size", table.line);
        }
        let Some(s) = &table.stated else {
            headers.push((table, end));
            continue;
        };
        let want = if s.bytes.contains(" to ") {
            assert!(table.rows[0][1].ends_with(&format!("1..={MAX_CARRIED}")));
            Linear(0, 1)
        } else {
            Linear(s.bytes.parse().expect("a length"), 0)
        };
        assert_eq!(end, want, "PROTOCOL.md:{}: the table's length", table.line);
    }
    // The headers in the document's order: version 2, version 1, and the header both
    // directions between a host and a device share (twice), each as long as the code's and
    // ending in its payload.
    let ends: Vec<(Linear, Linear)> = headers
        .iter()
        .map(|(table, end)| {
            let payload = table
                .rows
                .iter()
                .find(|[_, _, field]| field.starts_with("points") || field == "payload")
                .unwrap_or_else(|| panic!("PROTOCOL.md:{}: no payload", table.line));
            (linear(&payload[0]), *end)
        })
        .collect();
    assert_eq!(
        ends,
        [
            (Linear(HEADER_LEN, 0), Linear(HEADER_LEN + WIDE_POSE_LEN, 0)),
            (Linear(HEADER_LEN_V1, 0), Linear(HEADER_LEN_V1, POINT_LEN)),
            (Linear(frame::HEADER_LEN, 0), Linear(frame::HEADER_LEN, 1)),
            (Linear(frame::HEADER_LEN, 0), Linear(frame::HEADER_LEN, 1)),
        ],
        "PROTOCOL.md: the headers' lengths and the payloads they end in"
    );
    // Version 2's payloads by kind: points, pose and wide pose.
    let sizes: Vec<Linear> = headers[0]
        .0
        .rows
        .iter()
        .filter(|[offset, _, _]| *offset == HEADER_LEN.to_string())
        .map(|[_, size, _]| linear(size))
        .collect();
    assert_eq!(
        sizes,
        [
            Linear(0, POINT_LEN),
            Linear(POSE_LEN, 0),
            Linear(WIDE_POSE_LEN, 0)
        ]
    );
}

#[test]
fn lengths_read_as_written() {
    assert_eq!(linear("14"), Linear(14, 0));
    assert_eq!(linear("12 n"), Linear(0, 12));
    assert_eq!(linear("10 + 12 n"), Linear(10, 12));
    assert_eq!(linear("14 + n"), Linear(14, 1));
    assert_eq!(linear("n, 1..=240"), Linear(0, 1));
}
