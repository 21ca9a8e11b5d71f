//! The host's assembler of a device's frames ([`MapFrames`]) on any bytes: the property
//! `host/fuzz`'s `map_frames` target checks under cargo-fuzz (`scripts/fuzz.sh`) and the test
//! suite checks on mutations of the same seeds (`tests/tests/fuzzing.rs`).
//!
//! The same bytes fed whole and in pieces of other sizes give the same counts, entities, end
//! and map; no more entities than frames taken; the counts are those of a model written apart
//! from it (the bytes split at every `0x00`, each block COBS-decoded in place by the plain
//! decoder and read by `downlink::decode`, then PROTOCOL.md's "Sessions and boots"); and
//! `map_file` is `Ok` only for a file of the end frame's length and CRC-32 (and counts, when the
//! stream's are known) that the map decoder reads back with the end's count of entities. Since
//! a mutation almost never keeps that length and CRC, the bytes are fed once more with the end
//! frame's length and CRC made those of the map the model rebuilds from the same entities: the
//! assembler must then give exactly that map, and it must read back.

use std::collections::BTreeMap;

use mema_core::fuzz_checks::{crcs_made_right, plain_blocks};
use mema_core::link::crc32::crc32;
use mema_core::link::downlink::{
    self, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd, SessionStatus, map_checksum, stored_entity,
};
use mema_core::link::frame::Address;
use mema_core::map::{MapEntity, MapFile, encode_as};

use super::device::MapFrames;

/// The target's input: a header, then the device's bytes. The header: the piece size
/// (`1 + b`), whether every block's CRC is made right first (`b & 1`: so a mutation reaches
/// the frames' fields, as it does on a line whose CRC check missed it), the host's session
/// (u32), and the points and points frames of the stream it sent (u32 each; both `0`: not
/// known, nothing expected), little-endian.
pub const FRAMES_HEADER: usize = 2 + 4 + 4 + 4;

/// The target's input for the device's `bytes`: see [`FRAMES_HEADER`].
pub fn frames_input(
    piece: u8,
    crcs_right: bool,
    session: u32,
    expected: (u32, u32),
    bytes: &[u8],
) -> Vec<u8> {
    let mut data = vec![piece, u8::from(crcs_right)];
    for v in [session, expected.0, expected.1] {
        data.extend_from_slice(&v.to_le_bytes());
    }
    data.extend_from_slice(bytes);
    data
}

/// A property the assembler broke.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Violation {
    /// Fed in other pieces, it said something else (both accounts).
    Pieces { whole: String, pieces: String },
    /// It counted more entities than frames.
    MoreEntitiesThanFrames,
    /// Its counts or end are not the model's (both accounts).
    Model { got: String, expected: String },
    /// `map_file` gave a map that is not the end frame's, or does not read back.
    WrongMap(String),
}

/// What the assembler made of an input, when it kept its promises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Outcome {
    /// Frames of the session taken, entities among them.
    pub frames: u64,
    pub entities: usize,
    /// The end came, and the map came whole (as fed, and with its length and CRC made right).
    pub ended: bool,
    pub map: bool,
    pub map_made_right: bool,
}

/// Everything the assembler says, as one string to compare.
fn account(f: &MapFrames) -> String {
    let map = f.map_file().map(|m| m.map_err(|e| e.to_string()));
    format!(
        "{:?} started {} {:?} ended {} missing {:?} entities {:?} broken {:?} version {:?} \
         taken {} acked {} {:?} map {:?}",
        f.counts,
        f.started(),
        f.device_layout(),
        f.ended(),
        f.missing(),
        f.entities(),
        f.broken().map(|e| e.to_string()),
        f.other_version(),
        f.taken(),
        f.acked(),
        f.address(),
        map,
    )
}

fn feed(
    session: u32,
    expected: Option<(u32, u32)>,
    pieces: &mut dyn Iterator<Item = &[u8]>,
) -> MapFrames {
    let mut f = MapFrames::for_session(session);
    if let Some((points, frames)) = expected {
        f.expect(points, frames);
    }
    for piece in pieces {
        f.feed(piece);
    }
    f
}

/// `bytes` in pieces of the sizes `sizes` cycles through.
fn cut<'b>(bytes: &'b [u8], sizes: &[usize]) -> Vec<&'b [u8]> {
    let (mut out, mut at) = (Vec::new(), 0);
    for &n in sizes.iter().cycle() {
        if at >= bytes.len() {
            break;
        }
        let end = (at + n.max(1)).min(bytes.len());
        out.push(&bytes[at..end]);
        at = end;
    }
    out
}

/// What the session's frames say, by the model.
#[derive(Debug, Default)]
struct Model {
    frames: u64,
    refused: u64,
    foreign: u64,
    entities: BTreeMap<u32, MapEntity>,
    /// The last end frame of the session, and where its block is in the bytes.
    end: Option<(MapEnd, std::ops::Range<usize>, Address, u32)>,
}

fn model(session: u32, bytes: &[u8]) -> Model {
    let mut m = Model::default();
    let mut boot = None;
    plain_blocks(bytes, MAX_DOWN_FRAME_LEN, |span, raw| {
        let Some(Ok((from, sequence, frame))) = raw.map(downlink::decode) else {
            m.refused += 1;
            return;
        };
        // The session's frames: of its number, from the boot whose session frame said it
        // started it.
        let ours = match boot {
            Some(b) => from.boot == b && from.session == session,
            None => {
                let started = matches!(
                    frame,
                    DownFrame::Session {
                        status: SessionStatus::Started,
                        ..
                    }
                );
                if started && session != 0 && from.session == session {
                    boot = Some(from.boot);
                }
                boot.is_some()
            }
        };
        if !ours {
            m.foreign += 1;
            return;
        }
        m.frames += 1;
        match frame {
            DownFrame::Entity { index, entity } => {
                m.entities.insert(index, entity);
            }
            DownFrame::End(end) => m.end = Some((end, span, from, sequence)),
            _ => {}
        }
    });
    m
}

/// The map the model's entities make under `end`, if whole and encodable.
fn rebuilt(m: &Model, end: &MapEnd) -> Option<Vec<u8>> {
    let entities: Option<Vec<MapEntity>> = (0..end.entities)
        .map(|i| m.entities.get(&i).copied())
        .collect();
    let stored = entities?
        .into_iter()
        .map(|e| stored_entity(e, end.shift, end.layout));
    let origin: [f64; 3] = std::array::from_fn(|j| end.origin[j] + f64::from(end.shift[j]));
    let mut out = vec![0u8; end.layout.encoded_len(end.entities as usize)];
    let len = encode_as(end.layout, origin, stored, &mut out).ok()?;
    out.truncate(len);
    Some(out)
}

/// A map `map_file` gave: the end's length, CRC-32 and counts, and it reads back with the
/// end's count of entities.
fn check_map(map: &[u8], end: &MapEnd, expected: Option<(u32, u32)>) -> Result<(), Violation> {
    if map.len() != end.map_len as usize || map_checksum(map) != end.map_crc {
        return Err(Violation::WrongMap(format!(
            "{} bytes, CRC-32 {:08x}: the end says {} and {:08x}",
            map.len(),
            crc32(map),
            end.map_len,
            end.map_crc
        )));
    }
    if expected.is_some_and(|e| e != (end.points, end.frames)) {
        return Err(Violation::WrongMap("other counts than the stream's".into()));
    }
    match MapFile::new_checked(map) {
        Ok(file) if file.len() == end.entities as usize => Ok(()),
        Ok(file) => Err(Violation::WrongMap(format!("{} entities", file.len()))),
        Err(e) => Err(Violation::WrongMap(format!("does not read back: {e:?}"))),
    }
}

/// The assembler on a fuzz input ([`FRAMES_HEADER`], then the device's bytes).
pub fn map_frames(data: &[u8]) -> Result<Outcome, Violation> {
    let Some((header, bytes)) = data.split_first_chunk::<FRAMES_HEADER>() else {
        return Ok(Outcome::default());
    };
    let u32_at = |at: usize| {
        u32::from_le_bytes([header[at], header[at + 1], header[at + 2], header[at + 3]])
    };
    let piece = 1 + usize::from(header[0]);
    let session = u32_at(2);
    let expected = Some((u32_at(6), u32_at(10))).filter(|e| *e != (0, 0));
    let fixed;
    let bytes = if header[1] & 1 == 1 {
        let mut made = Vec::with_capacity(bytes.len() + 16);
        crcs_made_right(bytes, |piece| made.extend_from_slice(piece));
        fixed = made;
        &fixed[..]
    } else {
        bytes
    };
    let whole = feed(session, expected, &mut std::iter::once(bytes));
    let said = account(&whole);
    for sizes in [&[piece][..], &[1, piece, 3, 2 * piece + 1]] {
        let other = feed(session, expected, &mut cut(bytes, sizes).into_iter());
        let pieces = account(&other);
        if pieces != said {
            return Err(Violation::Pieces {
                whole: said,
                pieces,
            });
        }
    }
    let c = &whole.counts;
    if c.entities as u64 > c.frames {
        return Err(Violation::MoreEntitiesThanFrames);
    }
    let m = model(session, bytes);
    let got = (c.frames, c.refused, c.foreign, c.entities, whole.ended());
    let want = (
        m.frames,
        m.refused,
        m.foreign,
        m.entities.len(),
        m.end.is_some(),
    );
    if got != want {
        return Err(Violation::Model {
            got: format!("{got:?}"),
            expected: format!("{want:?}"),
        });
    }
    let mut outcome = Outcome {
        frames: c.frames,
        entities: c.entities,
        ended: m.end.is_some(),
        ..Outcome::default()
    };
    let Some((end, span, from, sequence)) = m.end.clone() else {
        return Ok(outcome);
    };
    if let Some(Ok(map)) = whole.map_file() {
        check_map(&map, &end, expected)?;
        outcome.map = true;
    }
    // Once more, the end frame's length and CRC those of the map the entities make.
    let Some(map) = rebuilt(&m, &end) else {
        return Ok(outcome);
    };
    let right = MapEnd {
        map_len: map.len() as u32,
        map_crc: map_checksum(&map),
        ..end
    };
    let mut sealed = [0u8; MAX_DOWN_FRAME_LEN];
    let Ok(n) = downlink::encode(from, sequence, &DownFrame::End(right), &mut sealed) else {
        return Ok(outcome);
    };
    let patched = [&bytes[..span.start], &sealed[..n - 1], &bytes[span.end..]].concat();
    let again = feed(session, expected, &mut std::iter::once(&patched[..]));
    match again.map_file() {
        Some(Ok(got)) if got == map => check_map(&got, &right, expected)?,
        // Only the stream's counts may keep it from being written.
        Some(Err(super::device::DeviceError::Counts { .. }))
            if expected.is_some_and(|e| e != (end.points, end.frames)) => {}
        other => {
            return Err(Violation::WrongMap(format!(
                "with its length and CRC made right: {:?}",
                other.map(|m| m.map(|b| b.len()).map_err(|e| e.to_string()))
            )));
        }
    }
    outcome.map_made_right = true;
    Ok(outcome)
}
