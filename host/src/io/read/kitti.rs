//! KITTI velodyne scans: headerless records of four little-endian f32 (x, y, z, reflectance).
//!
//! With no magic bytes to look for, the `.bin` extension is what selects this reader, and only
//! after every format with a signature has declined the bytes.

use super::stream::Input;
use super::{Cloud, Format, Points, ReadError};

const RECORD: usize = 16;

pub fn is_named_bin(name: &str) -> bool {
    std::path::Path::new(name)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("bin"))
}

pub fn read(input: &mut Input) -> Result<Cloud, ReadError> {
    let (ctx, len) = (input.ctx(), input.len());
    if !len.is_multiple_of(RECORD as u64) {
        return Err(ctx.truncated(format!(
            "{len} bytes is not a whole number of 16-byte KITTI records (x, y, z, reflectance as f32)"
        )));
    }
    let records = usize::try_from(len / RECORD as u64).unwrap_or(usize::MAX);
    let mut points = Points::with_capacity(ctx, records)?;
    let point = |record: &[u8]| {
        let mut xyz = [0.0f64; 3];
        for (c, raw) in xyz.iter_mut().zip(record.chunks_exact(4)) {
            let raw: [u8; 4] = raw.try_into().unwrap_or_default();
            *c = f64::from(f32::from_le_bytes(raw));
        }
        xyz
    };
    // Fewer only if the file shrank after its length was checked.
    if input.records(RECORD, records, |record| points.push(point(record)))? < records {
        return Err(input.ended(&format!("KITTI record {}", input.pos() / RECORD as u64)));
    }
    // A velodyne scan is in the sensor's own frame.
    points.set_sensor([0.0; 3]);
    points.finish(ctx, Format::KittiBin)
}

#[cfg(test)]
mod tests {
    use super::super::read_cloud_bytes;
    use super::super::testkit::{assert_same, shared};
    use super::*;

    /// A real scan re-encoded as KITTI records (reflectance 0.5) reads back point for point.
    #[test]
    fn a_real_cloud_as_kitti_records() {
        let car = read_cloud_bytes("car6.pcd", &shared("car6.pcd")).unwrap();
        let world: Vec<[f64; 3]> = car
            .points
            .iter()
            .map(|p| std::array::from_fn(|j| f64::from(p[j] + car.origin[j] as f32)))
            .collect();
        let mut bytes = Vec::new();
        for p in &world {
            for c in p.iter().map(|&c| c as f32).chain([0.5]) {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        let cloud = read_cloud_bytes("000000.bin", &bytes).unwrap();
        assert_eq!((cloud.format, cloud.slots), (Format::KittiBin, world.len()));
        let exact: Vec<[f64; 3]> = world
            .iter()
            .map(|p| p.map(|c| f64::from(c as f32)))
            .collect();
        assert_same(&cloud, &exact, "kitti");
        let e = read_cloud_bytes("cut.bin", &bytes[..bytes.len() - 3]).unwrap_err();
        assert!(matches!(e, ReadError::Truncated { .. }), "{e:?}");
        let nan = [f32::NAN.to_le_bytes(); 4].concat();
        let e = read_cloud_bytes("nan.bin", &nan).unwrap_err();
        assert!(
            matches!(e, ReadError::NoFinitePoints { slots: 1, .. }),
            "{e:?}"
        );
    }
}
