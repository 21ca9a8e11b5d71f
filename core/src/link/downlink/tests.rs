use super::*;
use crate::fit::FitParams;
use crate::link::crc32::crc32;
use crate::link::framing::decode_block;
use crate::map::encode_as;
use crate::shell::ShellParams;
use crate::stream::{Pacing, StreamMapper, StreamModel, StreamParams};
use crate::test_support::{OrFail, TestResult, damaged_blocks_are_refused, hex};

/// The examples' session and boot (PROTOCOL.md).
const FROM: Address = Address {
    session: 0x5E55_1011,
    boot: 7,
};

/// Tilted shells swept along x, so the mapper freezes the ones it leaves behind and its
/// shells turn.
fn swept() -> [Point3; 2000] {
    let mut pts = [Point3::default(); 2000];
    for (i, p) in pts.iter_mut().enumerate() {
        let shell = (i / 250) as f32;
        let (t, u) = (i as f32 * 0.618, i as f32 * 0.377);
        let (x, y) = (
            10.0 * shell + 0.5 * libm::cosf(t) * libm::sinf(u),
            0.3 * libm::sinf(t) * libm::sinf(u),
        );
        *p = Point3::new(x + 0.4 * y, y - 0.04 * x, 0.2 * libm::cosf(u));
    }
    pts
}

fn params(model: StreamModel) -> StreamParams {
    StreamParams {
        fit: FitParams::default(),
        seed: 0,
        max_clusters: 6,
        max_frozen: 12,
        refit_interval: 64,
        tolerance: 0.0,
        model,
        pacing: Pacing::NONE,
        final_clusters: 0,
    }
}

/// The device's map, sent as frames and rebuilt by a host from them alone, is its `.mema`
/// file byte for byte, in both models; the end frame's length and CRC say so.
#[test]
fn a_host_rebuilds_the_devices_file_from_the_frames() -> TestResult {
    let origin = [512_000.25, -3.5, 1_024.0];
    for model in [
        StreamModel::Paper,
        StreamModel::Shells(ShellParams::DEFAULT),
    ] {
        let mut m = StreamMapper::<6, 64, 12>::new(params(model));
        m.add_all(&swept());
        m.finish();
        let mut file = [0u8; 2048];
        let len = m.encode_into(origin, &mut file).or_fail("the map fits")?;
        let file = file.get(..len).or_fail("its length")?;
        let layout = m.layout();
        // The device's side: every entity, then the end.
        let mut wire = [0u8; 8192];
        let mut at = 0;
        let mut sequence = 0u32;
        let mut send = |frame: DownFrame, wire: &mut [u8], at: &mut usize| -> TestResult {
            let out = wire.get_mut(*at..).or_fail("room on the wire")?;
            *at += encode(FROM, sequence, &frame, out).or_fail("encodes")?;
            sequence += 1;
            Ok(())
        };
        let mut count = 0u32;
        for (index, entity) in m.entities().enumerate() {
            let index = u32::try_from(index).or_fail("index")?;
            send(DownFrame::Entity { index, entity }, &mut wire, &mut at)?;
            count += 1;
        }
        let end = MapEnd {
            entities: count,
            layout,
            shift: m.file_shift(layout),
            origin,
            map_len: u32::try_from(len).or_fail("length")?,
            map_crc: map_checksum(file),
            points: 2000,
            frames: 0,
        };
        send(DownFrame::End(end), &mut wire, &mut at)?;
        // The host's side: blocks between delimiters, decoded, in sequence.
        let mut entities: heapless::Vec<MapEntity, 32> = heapless::Vec::new();
        let mut got_end = None;
        let mut expected = 0u32;
        for block in wire.get_mut(..at).or_fail("sent")?.split_mut(|&b| b == 0) {
            if block.is_empty() {
                continue;
            }
            let raw = decode_block(block).or_fail("a block")?;
            let (from, seq, frame) = decode(raw).or_fail("a sent frame decodes")?;
            assert_eq!((from, seq), (FROM, expected));
            expected += 1;
            match frame {
                DownFrame::Entity { index, entity } => {
                    assert_eq!(index as usize, entities.len());
                    entities.push(entity).or_fail("room")?;
                }
                DownFrame::End(end) => got_end = Some(end),
                DownFrame::Progress { .. }
                | DownFrame::Timing(_)
                | DownFrame::Answer { .. }
                | DownFrame::Session { .. }
                | DownFrame::Retract { .. } => {
                    return Err("no progress, timing or retraction was sent");
                }
            }
        }
        let end = got_end.or_fail("an end frame")?;
        assert_eq!(end.entities as usize, entities.len());
        let file_origin: [f64; 3] =
            core::array::from_fn(|j| end.origin[j] + f64::from(end.shift[j]));
        let stored = entities
            .iter()
            .map(|e| stored_entity(*e, end.shift, end.layout));
        let mut rebuilt = [0u8; 2048];
        let n = encode_as(end.layout, file_origin, stored, &mut rebuilt).or_fail("rebuilds")?;
        let rebuilt = rebuilt.get(..n).or_fail("rebuilt")?;
        assert_eq!(rebuilt, file);
        assert_eq!(
            (n as u32, map_checksum(rebuilt)),
            (end.map_len, end.map_crc)
        );
        // The whole file's CRC is the residue, the same for any map: never the check.
        assert_eq!(crc32(rebuilt), 0x2144_df1c);
        assert!(
            !m.frozen().is_empty(),
            "the sweep froze nothing: the test needs frozen entities"
        );
    }
    Ok(())
}

/// Every flipped byte and every cut of a frame is refused, never a wrong frame or a panic.
#[test]
fn corrupt_and_cut_frames_are_refused() -> TestResult {
    let entity = MapEntity {
        entity: Entity {
            center: Point3::new(1.5, -2.0, 0.25),
            weights: [4.0, 0.0, 100.0],
            rotation: Rotation::from_quaternion([0.1, -0.3, 0.2, 0.9]).unwrap_or_default(),
        },
        kind: EntityKind::Pseudocylinder,
    };
    let frame = DownFrame::Entity { index: 7, entity };
    let mut sent = [0u8; MAX_DOWN_FRAME_LEN];
    let n = encode(FROM, 41, &frame, &mut sent).or_fail("encodes")?;
    let mut block = sent;
    let block_len = n - 1;
    let raw = decode_block(block.get_mut(..block_len).or_fail("block")?).or_fail("COBS")?;
    assert_eq!(decode(raw).or_fail("decodes")?, (FROM, 41, frame));
    damaged_blocks_are_refused(sent, block_len, |b| {
        decode_block(b).is_ok_and(|raw| decode(raw).is_ok())
    })?;
    let progress = DownFrame::Progress {
        taken: u32::MAX - 3,
        frames: 102,
        next: 7,
        refused: u32::MAX,
    };
    let timing = DownFrame::Timing(DeviceTiming {
        busy_ticks: 1 << 40,
        interrupt_ticks: 3,
        longest_tick: u64::MAX,
        calib_ticks: 0,
        calib_insns: 2_000_000,
        stack_bytes: 5_000,
        busy_cycles: u64::MAX - 1,
        ring_overruns: 7,
        line_overruns: u32::MAX,
    });
    let answer = DownFrame::Answer {
        query: 9,
        ray: true,
        entity: u32::MAX,
        value: f64::INFINITY,
        ticks: 123_456,
    };
    let session = DownFrame::Session {
        status: SessionStatus::Refused { reason: 200 },
        layout: DeviceLayout {
            capacity: u32::MAX,
            working: 0,
            model: 9,
        },
    };
    let retract = DownFrame::Retract {
        index: MAX_MAP_ENTITIES - 1,
    };
    for frame in [progress, timing, answer, session, retract] {
        let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
        let m = encode(FROM, u32::MAX, &frame, &mut wire).or_fail("encodes")?;
        let raw = decode_block(wire.get_mut(..m - 1).or_fail("block")?).or_fail("COBS")?;
        assert_eq!(decode(raw).or_fail("decodes")?, (FROM, u32::MAX, frame));
    }
    Ok(())
}

/// PROTOCOL.md's device-to-host examples, whose bytes were computed independently (Python's
/// `struct`, `zlib.crc32` and a COBS written from its definition): mema emits exactly them and
/// reads them back.
#[test]
fn protocol_examples() -> TestResult {
    let entity = DownFrame::Entity {
        index: 0,
        entity: MapEntity {
            entity: Entity {
                center: Point3::new(1.5, -2.0, 0.25),
                weights: [4.0, 0.0, 100.0],
                rotation: Rotation {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1.0,
                },
            },
            kind: EntityKind::Pseudocylinder,
        },
    };
    let progress = DownFrame::Progress {
        taken: 3124,
        frames: 2,
        next: 13,
        refused: 1,
    };
    let end = DownFrame::End(MapEnd {
        entities: 1,
        layout: Layout::Oriented,
        shift: [0.5, 0.0, -1.0],
        origin: [512_000.25, -3.5, 1_024.0],
        map_len: 86,
        map_crc: 0x1234_5678,
        points: 256,
        frames: 2,
    });
    let layout = DeviceLayout {
        capacity: 700,
        working: 150,
        model: 1,
    };
    let booted = DownFrame::Session {
        status: SessionStatus::Booted,
        layout,
    };
    let started = DownFrame::Session {
        status: SessionStatus::Started,
        layout,
    };
    let timing = DownFrame::Timing(DeviceTiming {
        busy_ticks: 2_000_000,
        interrupt_ticks: 150_000,
        longest_tick: 90_000,
        calib_ticks: 1_000,
        calib_insns: 2_500,
        stack_bytes: 5_400,
        busy_cycles: 3_000_000,
        ring_overruns: 0,
        line_overruns: 2,
    });
    let answer = DownFrame::Answer {
        query: 77,
        ray: true,
        entity: 3,
        value: 2.5,
        ticks: 41_000,
    };
    let no_session = Address {
        session: 0,
        boot: FROM.boot,
    };
    let examples = [
        (
            no_session,
            0,
            booted,
            "03 83 05 01 01 01 02 07 01 01 01 01 01 01 01 01 03 bc 02 01 02 96 01 01 06 01 8e 2f \
             21 16 00",
        ),
        (
            FROM,
            1,
            started,
            "08 83 05 11 10 55 5e 07 01 01 02 01 01 01 02 01 03 bc 02 01 02 96 01 01 06 01 13 95 \
             42 a3 00",
        ),
        (
            FROM,
            2,
            entity,
            "02 83 06 11 10 55 5e 07 01 01 02 02 01 01 01 01 01 01 02 02 01 03 c0 3f 01 01 02 c0 \
             01 03 80 3e 01 03 80 40 01 01 01 01 01 03 c8 42 01 01 01 01 01 01 01 01 01 01 01 01 \
             01 07 80 3f 46 08 70 a3 00",
        ),
        (
            FROM,
            3,
            progress,
            "08 83 02 11 10 55 5e 07 01 01 02 03 01 01 03 34 0c 01 02 02 01 01 02 0d 01 01 02 01 \
             01 01 05 6d bb b3 c1 00",
        ),
        (
            FROM,
            4,
            end,
            "08 83 01 11 10 55 5e 07 01 01 02 04 01 01 02 01 01 01 02 01 01 01 01 01 01 01 01 01 \
             01 01 01 01 01 01 02 3f 01 01 01 01 01 03 80 bf 01 01 01 05 01 40 1f 41 01 01 01 01 \
             01 03 0c c0 01 01 01 01 01 04 90 40 56 01 01 05 78 56 34 12 02 01 01 02 02 01 01 05 \
             a4 50 7a 5b 00",
        ),
        (
            FROM,
            5,
            timing,
            "08 83 03 11 10 55 5e 07 01 01 02 05 01 01 04 80 84 1e 01 01 01 01 04 f0 49 02 01 01 \
             01 01 04 90 5f 01 01 01 01 01 03 e8 03 01 01 01 01 01 03 c4 09 01 01 01 01 01 03 18 \
             15 01 01 01 01 01 04 c0 c6 2d 01 01 01 01 01 01 01 01 02 02 01 01 05 3a c9 95 26 00",
        ),
        (
            FROM,
            6,
            answer,
            "08 83 04 11 10 55 5e 07 01 01 02 06 01 01 02 4d 01 01 03 01 03 01 01 01 01 01 01 01 \
             01 05 04 40 28 a0 01 05 1e 81 7b e9 00",
        ),
    ];
    for (from, sequence, frame, wire) in examples {
        let mut want = [0u8; MAX_DOWN_FRAME_LEN];
        let n = hex(wire, &mut want)?;
        let mut got = [0u8; MAX_DOWN_FRAME_LEN];
        let m = encode(from, sequence, &frame, &mut got).or_fail("encodes")?;
        assert_eq!(got.get(..m), want.get(..n), "sequence {sequence}");
        let raw = decode_block(want.get_mut(..n - 1).or_fail("block")?).or_fail("COBS")?;
        assert_eq!(decode(raw).or_fail("decodes")?, (from, sequence, frame));
    }
    Ok(())
}

/// An end frame of the axis-aligned or oriented layout whose grid is not `0` (PROTOCOL.md), a
/// `-0.0` included, is refused: read as its layout, it would re-encode to other bytes, a second
/// end frame for one map (what the `downlink_decoder` fuzz target checks).
#[test]
fn an_end_with_a_grid_outside_the_quantized_layout_is_refused() -> TestResult {
    for layout in [Layout::AxisAligned, Layout::Oriented] {
        let end = DownFrame::End(MapEnd {
            entities: 3,
            layout,
            shift: [0.5, 0.0, -1.0],
            origin: [512_000.25, -3.5, 1_024.0],
            map_len: 86,
            map_crc: 0x1234_5678,
            points: 256,
            frames: 2,
        });
        let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
        let n = encode(FROM, 4, &end, &mut wire).or_fail("encodes")?;
        let raw = decode_block(wire.get_mut(..n - 1).or_fail("block")?).or_fail("COBS")?;
        assert_eq!(decode(raw).or_fail("decodes")?.2, end);
        let mut copy = [0u8; MAX_RAW_LEN];
        let copy = copy.get_mut(..raw.len()).or_fail("room")?;
        copy.copy_from_slice(raw);
        // The grid's first f32 (payload offset 5) as -0.0, then as 0.5.
        for (at, byte) in [(HEADER_LEN + 8, 0x80), (HEADER_LEN + 8, 0x3f)] {
            *copy.get_mut(at).or_fail("grid")? = byte;
            let body = copy.len() - CRC_LEN;
            let crc = crc32(copy.get(..body).or_fail("body")?);
            copy.get_mut(body..)
                .or_fail("crc")?
                .copy_from_slice(&crc.to_le_bytes());
            assert_eq!(
                decode(copy).map(|d| d.2),
                Err(LinkError::Value),
                "{layout:?}"
            );
        }
    }
    Ok(())
}

/// An entity frame whose rotation is not a unit quaternion (within the map file's 1e-5 on the
/// squared norm) is refused: the host would rebuild from it a map no reader takes, though its
/// length and CRC were the device's (the `map_frames` fuzz check's finding, on an end saying
/// the oriented layout). One within the tolerance is taken.
#[test]
fn an_entity_whose_rotation_is_not_unit_is_refused() -> TestResult {
    for (w, taken) in [(2.0f32, false), (1.0 + 1e-5, false), (1.0 + 2e-6, true)] {
        let entity = MapEntity {
            entity: Entity {
                center: Point3::new(1.5, -2.0, 0.25),
                weights: [4.0, 1.0, 100.0],
                rotation: Rotation {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w,
                },
            },
            kind: EntityKind::Ellipsoid,
        };
        let frame = DownFrame::Entity { index: 3, entity };
        let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
        let n = encode(FROM, 9, &frame, &mut wire).or_fail("encodes")?;
        let raw = decode_block(wire.get_mut(..n - 1).or_fail("block")?).or_fail("COBS")?;
        let got = decode(raw);
        if taken {
            assert_eq!(got.or_fail("decodes")?.2, frame);
        } else {
            assert_eq!(got.map(|d| d.2), Err(LinkError::Value), "w = {w}");
        }
    }
    Ok(())
}
