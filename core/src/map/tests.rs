use super::*;
use crate::Point3;
use crate::test_support::{OrFail, TestResult};

fn sample_oriented() -> Result<Map<4>, &'static str> {
    let mut map = sample()?;
    let turned = map
        .entities()
        .iter()
        .enumerate()
        .map(|(i, e)| MapEntity {
            entity: e.entity.with_rotation(
                crate::Rotation::from_quaternion([0.1 * i as f64, -0.3, 0.2, 0.9])
                    .unwrap_or_default(),
            ),
            kind: e.kind,
        })
        .collect::<heapless::Vec<MapEntity, 4>>();
    map.clear();
    for e in turned {
        map.push(e).or_fail("room for four")?;
    }
    Ok(map)
}

#[test]
fn every_layout_round_trips_and_rejects_every_corruption() -> TestResult {
    let map = sample_oriented()?;
    let grid = Quantization::for_entities(map.entities().iter().copied());
    for layout in [Layout::Oriented, Layout::Quantized(grid)] {
        let mut buf = [0u8; HEADER_V2_LEN + ORIENTED_LEN * 4 + CRC_LEN];
        let n = encode_as(layout, map.origin, map.entities().iter().copied(), &mut buf)
            .or_fail("fits")?;
        let buf = buf.get(..n).or_fail("written")?;
        let file = MapFile::new_checked(buf).or_fail("valid")?;
        assert_eq!(file.layout(), layout);
        assert_eq!(file.origin(), map.origin);
        for (read, wrote) in file.entities().zip(map.entities()) {
            let want = match layout {
                Layout::Quantized(grid) => grid.quantize(*wrote),
                _ => *wrote,
            };
            assert_eq!(read, want);
        }
        for cut in 0..buf.len() {
            assert!(MapFile::new_checked(&buf[..cut]).is_err(), "cut at {cut}");
        }
        let mut bad = [0u8; HEADER_V2_LEN + ORIENTED_LEN * 4 + CRC_LEN];
        for byte in 0..n {
            for bit in 0..8 {
                bad[..n].copy_from_slice(buf);
                bad[byte] ^= 1 << bit;
                assert!(
                    MapFile::new_checked(&bad[..n]).is_err(),
                    "flip {byte}.{bit}"
                );
            }
        }
    }
    // Version 1 cannot hold a rotation, and says which entity has one.
    let mut small = [0u8; encoded_len(4)];
    assert_eq!(
        encode(map.origin, map.entities(), &mut small),
        Err(EncodeError::Oriented { index: 0 })
    );
    Ok(())
}

fn sample() -> Result<Map<4>, &'static str> {
    let mut map = Map::<4>::new([1e6, -2.5, 300.125]);
    for (i, kind) in EntityKind::ALL.into_iter().enumerate() {
        let w = i as f32;
        map.push(MapEntity {
            entity: Entity::axis_aligned(Point3::new(w, -w, 0.5), [w, 1.0, 0.0]),
            kind,
        })
        .or_fail("room for four")?;
    }
    Ok(map)
}

#[test]
fn round_trip_and_capacity() -> TestResult {
    let mut map = sample()?;
    let mut buf = [0u8; encoded_len(4)];
    let n = encode(map.origin, map.entities(), &mut buf).or_fail("fits")?;
    assert_eq!(n, buf.len());
    let file = MapFile::new_checked(&buf).or_fail("valid")?;
    assert_eq!(Map::<4>::from_file(&file).or_fail("fits")?, map);
    assert_eq!(
        Map::<3>::from_file(&file),
        Err(CapacityExceeded { capacity: 3 })
    );
    let extra = map.entities()[0];
    assert_eq!(map.push(extra), Err(CapacityExceeded { capacity: 4 }));
    assert_eq!(map.entities().len(), 4);
    let mut small = [0u8; 10];
    assert!(matches!(
        encode(map.origin, map.entities(), &mut small),
        Err(EncodeError::BufferTooSmall { .. })
    ));
    Ok(())
}

#[test]
fn every_corruption_is_rejected() -> TestResult {
    let map = sample()?;
    let mut buf = [0u8; encoded_len(4)];
    encode(map.origin, map.entities(), &mut buf).or_fail("fits")?;
    for cut in 0..buf.len() {
        assert!(MapFile::new_checked(&buf[..cut]).is_err(), "cut at {cut}");
    }
    for byte in 0..buf.len() {
        for bit in 0..8 {
            let mut bad = buf;
            bad[byte] ^= 1 << bit;
            assert!(MapFile::new_checked(&bad).is_err(), "flip {byte}.{bit}");
        }
    }
    Ok(())
}

#[test]
fn a_rotation_code_decodes_to_a_rotation_with_the_same_code() {
    use crate::map::record::{rotation_code, rotation_of_code};
    use crate::rotation::Rotation;
    // Random unit quaternions, and turns about each axis near 90 degrees, where two components
    // are within a code step of each other (the case a car6 shell map found: its file read
    // back as a rotation 0.03 degrees off the map in memory).
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut checked = 0;
    for i in 0..200_000 {
        let q = if i % 2 == 0 {
            [next(), next(), next(), next()]
        } else {
            // cos and sin of about 45 degrees in two components, small others.
            let t = core::f64::consts::FRAC_PI_4 + next() * 1e-3;
            let (c, n) = (libm::cos(t), libm::sin(t));
            let small = [next() * 1e-2, next() * 1e-2];
            match i % 6 {
                1 => [c, n, small[0], small[1]],
                3 => [small[0], c, -n, small[1]],
                _ => [small[0], small[1], n, -c],
            }
        };
        let Some(r) = Rotation::from_quaternion(q) else {
            continue;
        };
        let code = rotation_code(&r);
        assert_eq!(rotation_code(&rotation_of_code(code)), code, "{q:?}");
        checked += 1;
    }
    assert!(checked > 190_000);
}

/// A map with a free-space part: its images come back exactly, its entities as without one,
/// and every cut and every flipped bit is refused; the axis-aligned layout cannot hold one.
#[test]
fn a_free_space_part_round_trips_and_rejects_every_corruption() -> TestResult {
    let map = sample_oriented()?;
    let geometry = |x: f32, rows: u16, columns: u16| Geometry {
        origin: Point3::new(x, -1.0, 0.5),
        near: 0.25,
        elevation: [-0.4, 0.3],
        azimuth: [-3.0, 6.0],
        rows,
        columns,
    };
    let cells_a: [u8; 6] = [0, 7, 254, 255, 31, 100];
    let cells_b: [u8; 4] = [9, 255, 255, 1];
    let images = [
        (geometry(2.0, 2, 3), &cells_a[..]),
        (geometry(-4.0, 1, 4), &cells_b[..]),
    ];
    let grid = Quantization::for_entities(map.entities().iter().copied());
    for layout in [Layout::Oriented, Layout::Quantized(grid)] {
        let mut buf = [0u8; 512];
        let mut n = 0;
        let written = encode_pieces_with(
            layout,
            map.origin,
            map.entities().iter().copied(),
            images.iter().copied(),
            |piece| {
                if let Some(out) = buf.get_mut(n..n + piece.len()) {
                    out.copy_from_slice(piece);
                }
                n += piece.len();
            },
        )
        .or_fail("encodes")?;
        assert_eq!(written, n);
        assert_eq!(n, layout.encoded_len(4) + 6 + 2 * 36 + 6 + 4);
        let bytes = buf.get(..n).or_fail("written")?;
        let file = MapFile::new_checked(bytes).or_fail("valid")?;
        assert!(file.free_space().eq(images.iter().copied()));
        assert_eq!(file.layout(), layout);
        assert_eq!(file.entities().count(), 4);
        for cut in 0..n {
            assert!(MapFile::new_checked(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut bad = [0u8; 512];
        for byte in 0..n {
            for bit in 0..8 {
                bad[..n].copy_from_slice(bytes);
                bad[byte] ^= 1 << bit;
                assert!(
                    MapFile::new_checked(&bad[..n]).is_err(),
                    "flip {byte}.{bit}"
                );
            }
        }
        // Without images, the file is the map's as before, and says it has none.
        let mut plain = [0u8; 512];
        let m = encode_as(
            layout,
            map.origin,
            map.entities().iter().copied(),
            &mut plain,
        )
        .or_fail("encodes")?;
        let plain = MapFile::new_checked(plain.get(..m).or_fail("written")?).or_fail("valid")?;
        assert_eq!(plain.free_space().count(), 0);
    }
    let mut sink = |_: &[u8]| {};
    assert_eq!(
        encode_pieces_with(
            Layout::Oriented,
            map.origin,
            map.entities().iter().copied(),
            [(geometry(0.0, 2, 2), &cells_a[..])].into_iter(),
            &mut sink,
        ),
        Err(EncodeError::InvalidFreeSpace),
        "six codes for four pixels"
    );
    assert_eq!(
        encode_pieces_with(
            Layout::AxisAligned,
            map.origin,
            core::iter::empty(),
            images.iter().copied(),
            &mut sink,
        ),
        Err(EncodeError::InvalidFreeSpace)
    );
    Ok(())
}
