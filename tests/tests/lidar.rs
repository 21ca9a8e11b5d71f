use crate::util::{Dir, MemaCommand, shared};
use std::io::{Cursor, Seek, SeekFrom};

/// The fields of a LAS header that the checks need, read as the specification lays them out.
pub(crate) struct LasHeader {
    points: u64,
    data_at: u64,
    record_len: usize,
    scale: [f64; 3],
    offset: [f64; 3],
    vlrs: Vec<(u16, Vec<u8>)>,
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

pub(crate) fn las_header(b: &[u8]) -> LasHeader {
    assert_eq!(&b[..4], b"LASF");
    let legacy = u64::from(u32_at(b, 107));
    let points = if b[25] >= 4 && legacy == 0 {
        u64::from_le_bytes(b[247..255].try_into().unwrap())
    } else {
        legacy
    };
    let mut vlrs = Vec::new();
    let mut at = usize::from(u16_at(b, 94));
    for _ in 0..u32_at(b, 100) {
        let (id, len) = (u16_at(b, at + 18), usize::from(u16_at(b, at + 20)));
        vlrs.push((id, b[at + 54..at + 54 + len].to_vec()));
        at += 54 + len;
    }
    LasHeader {
        points,
        data_at: u64::from(u32_at(b, 96)),
        record_len: usize::from(u16_at(b, 105)),
        scale: [131, 139, 147].map(|at| f64_at(b, at)),
        offset: [155, 163, 171].map(|at| f64_at(b, at)),
        vlrs,
    }
}

/// Every point's scaled coordinates from the raw i32 records; LAZ records are decompressed
/// with the `laz` crate directly, bypassing the `las` crate that mema reads through.
pub(crate) fn raw_points(b: &[u8]) -> Vec<[f64; 3]> {
    let h = las_header(b);
    let scaled = |r: &[u8]| {
        std::array::from_fn(|j| {
            let raw = i32::from_le_bytes(r[4 * j..4 * j + 4].try_into().unwrap());
            f64::from(raw) * h.scale[j] + h.offset[j]
        })
    };
    if b[104] & 0x80 == 0 {
        let data = &b[h.data_at as usize..];
        return data
            .chunks_exact(h.record_len)
            .take(h.points as usize)
            .map(scaled)
            .collect();
    }
    let (_, vlr) = h
        .vlrs
        .iter()
        .find(|(id, _)| *id == 22204)
        .expect("laszip VLR");
    let vlr = laz::LazVlr::from_buffer(vlr).expect("laszip VLR parses");
    let mut source = Cursor::new(b);
    source.seek(SeekFrom::Start(h.data_at)).unwrap();
    let mut d = laz::LasZipDecompressor::new(source, vlr).expect("decompressor");
    let mut record = vec![0u8; h.record_len];
    (0..h.points)
        .map(|_| {
            d.decompress_one(&mut record).expect("decompress");
            scaled(&record)
        })
        .collect()
}

const LIDAR: [(&str, &str); 3] = [
    ("simple.las", "10"),
    ("vegetation_1_3.las", "100"),
    ("autzen_trim.laz", "300"),
];

#[test]
fn shared_lidar_files_read_with_header_counts_and_round_trip_within_the_scale() {
    for (name, _) in LIDAR {
        let bytes = std::fs::read(shared(name)).unwrap();
        let h = las_header(&bytes);
        let cloud = mema::io::read::read_cloud(&shared(name)).unwrap();
        assert_eq!(cloud.slots as u64, h.points, "{name}");
        let raw = raw_points(&bytes);
        assert_eq!(raw.len(), cloud.points.len(), "{name}");
        for (i, (want, got)) in raw.iter().zip(&cloud.points).enumerate() {
            for j in 0..3 {
                let err = (cloud.origin[j] + f64::from(got[j]) - want[j]).abs();
                assert!(
                    err <= h.scale[j] / 2.0,
                    "{name} point {i} axis {j}: off by {err}"
                );
            }
        }
    }
}

#[test]
fn shared_lidar_maps_evaluate_with_finite_errors() {
    let dir = Dir::new("lidar-maps");
    for (name, k) in LIDAR {
        let out = dir.join(&format!("{name}.mema"));
        let mapped = MemaCommand::new(&dir)
            .arg("map")
            .arg(shared(name))
            .args(["-k", k, "--json", "-o"])
            .arg(&out)
            .run()
            .assert_ok()
            .json();
        let h = las_header(&std::fs::read(shared(name)).unwrap());
        assert_eq!(mapped["memory"]["points"], h.points, "{name}");
        assert_eq!(mapped["filter"]["read"], h.points, "{name}");
        assert!(mapped["filter"]["cropped"].is_null());
        let eval = MemaCommand::new(&dir)
            .arg("eval")
            .arg(shared(name))
            .arg(&out)
            .arg("--json")
            .run()
            .assert_ok()
            .json();
        assert_eq!(eval["points"], h.points);
        for key in ["mean", "std", "max", "min", "total"] {
            let v = eval[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v >= 0.0, "{name}: {key} = {v}");
        }
    }
}

/// `--crop` and `--voxel` against counts computed here from the raw records. The box and the
/// voxel edge are chosen off the file's integer grid, so no point sits on a boundary where the
/// f32 round trip could move it across.
#[test]
fn crop_and_voxel_counts_match_an_independent_computation() {
    let dir = Dir::new("crop-voxel");
    let bytes = std::fs::read(shared("vegetation_1_3.las")).unwrap();
    let h = las_header(&bytes);
    let raw = raw_points(&bytes);
    let axis = |j: usize| raw.iter().map(move |p| p[j]);
    let lo = [0, 1, 2].map(|j| axis(j).fold(f64::MAX, f64::min));
    let hi = [0, 1, 2].map(|j| axis(j).fold(f64::MIN, f64::max));
    let off_grid = |v: f64, j: usize| {
        let steps = ((v - h.offset[j]) / h.scale[j]).floor();
        h.offset[j] + (steps + 0.5) * h.scale[j]
    };
    let min = [0, 1, 2].map(|j| off_grid(lo[j] + 0.2 * (hi[j] - lo[j]), j));
    let max = [0, 1, 2].map(|j| off_grid(lo[j] + 0.9 * (hi[j] - lo[j]), j));
    let inside: Vec<[f64; 3]> = raw
        .iter()
        .copied()
        .filter(|p| (0..3).all(|j| min[j] <= p[j] && p[j] <= max[j]))
        .collect();
    let size = 0.7013 * (hi[0] - lo[0]) / 50.0;
    let voxels: std::collections::HashSet<[i64; 3]> = inside
        .iter()
        .map(|p| p.map(|c| (c / size).floor() as i64))
        .collect();
    let near_a_face = inside
        .iter()
        .filter(|p| {
            p.iter()
                .any(|c| ((c / size) - (c / size).round()).abs() * size < 1e-6)
        })
        .count();
    let crop = format!(
        "{},{},{},{},{},{}",
        min[0], min[1], min[2], max[0], max[1], max[2]
    );
    let report = MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("vegetation_1_3.las"))
        .args([
            "-k",
            "20",
            "--crop",
            &crop,
            "--voxel",
            &size.to_string(),
            "--json",
            "-o",
        ])
        .arg(dir.join("v.mema"))
        .run()
        .assert_ok()
        .json();
    assert_eq!(report["filter"]["read"], h.points);
    assert_eq!(report["filter"]["cropped"], inside.len());
    let got = report["filter"]["voxelized"].as_u64().unwrap() as usize;
    assert!(
        got.abs_diff(voxels.len()) <= near_a_face,
        "{got} vs {}",
        voxels.len()
    );
    assert!(voxels.len() < inside.len() && inside.len() < raw.len());
    assert_eq!(report["memory"]["points"].as_u64(), Some(got as u64));
    // The written map sits where the crop box is.
    let map = mema::io::mapfile::HostMap::read(&dir.join("v.mema")).unwrap();
    for e in &map.entities {
        let c = map.world_center(&e.entity);
        assert!(
            (0..3).all(|j| min[j] - 1e-3 <= c[j] && c[j] <= max[j] + 1e-3),
            "{c:?}"
        );
    }
}

#[test]
fn kitti_scans_map_end_to_end_and_bad_filters_are_usage_errors() {
    let dir = Dir::new("kitti");
    let car = mema::io::read::read_cloud(&shared("car6.pcd")).unwrap();
    let mut bytes = Vec::new();
    for p in &car.points {
        let world = [0, 1, 2].map(|j| (car.origin[j] + f64::from(p[j])) as f32);
        for c in world.into_iter().chain([0.25]) {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let bin = dir.write("000042.bin", &bytes);
    let report = MemaCommand::new(&dir)
        .arg("map")
        .arg(&bin)
        .args(["-k", "50", "--json", "-o", "k.mema"])
        .run()
        .assert_ok()
        .json();
    assert_eq!(
        report["memory"]["points"].as_u64(),
        Some(car.points.len() as u64)
    );
    let cut = dir.write("cut.bin", &bytes[..bytes.len() - 6]);
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&cut)
        .args(["-k", "5", "-o", "c.mema"])
        .run()
        .assert_error(1, "cut.bin: truncated");
    let las = std::fs::read(shared("simple.las")).unwrap();
    let cut = dir.write("cut.las", &las[..las.len() / 2]);
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&cut)
        .args(["-k", "5", "-o", "c.mema"])
        .run()
        .assert_error(1, "cut.las: truncated");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&bin)
        .args(["-k", "5", "--voxel=0", "-o", "c.mema"])
        .run()
        .assert_error(2, "--voxel 0 must be");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(&bin)
        .args([
            "-k",
            "5",
            "--crop",
            "100,100,100,101,101,101",
            "-o",
            "c.mema",
        ])
        .run()
        .assert_error(1, "leaves no points");
    assert!(!dir.join("c.mema").exists());
}
