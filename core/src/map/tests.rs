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
