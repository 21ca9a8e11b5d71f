//! `.mema` versions 1 and 2, checked against files written and decoded here from the layout the
//! core's module doc documents (not through the core's codec).

use crate::guides::{says, thousands};
use crate::util::{Dir, MemaCommand, shared};
use mema::io::mapfile::HostMap;
use mema_core::map::record::Quantization;

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

#[test]
fn a_version_1_file_written_by_hand_still_loads() {
    let dir = Dir::new("map-v1");
    let origin = [631_000.5f64, 4_833_000.25, 120.0];
    // (centre, weights, kind): an ellipsoid and a pseudocylinder along z.
    let entities = [
        ([0.5f32, -1.0, 2.0], [4.0f32, 1.0, 0.25], 0u8),
        ([-3.0f32, 0.0, 0.125], [16.0f32, 16.0, 0.0], 2u8),
    ];
    let mut bytes = b"MEMA".to_vec();
    bytes.extend(1u16.to_le_bytes());
    bytes.extend(0u16.to_le_bytes());
    for v in origin {
        bytes.extend(v.to_le_bytes());
    }
    bytes.extend((entities.len() as u32).to_le_bytes());
    for (c, w, kind) in entities {
        for v in c.iter().chain(w.iter()) {
            bytes.extend(v.to_le_bytes());
        }
        bytes.push(kind);
    }
    bytes.extend(crc32fast::hash(&bytes).to_le_bytes());
    let path = dir.write("old.mema", &bytes);
    let map = HostMap::read(&path).expect("version 1 loads");
    assert_eq!(map.origin, origin);
    for (e, (c, w, _)) in map.entities.iter().zip(entities) {
        assert_eq!(e.entity.center.to_array(), c);
        assert_eq!(e.entity.weights, w);
        assert!(e.entity.rotation.is_identity());
    }
    assert_eq!(map.entities[1].kind.name(), "pseudocylinder");
    let info = MemaCommand::new(&dir)
        .arg("info")
        .arg(&path)
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    assert_eq!(info["entities"], 2);
    assert_eq!(info["oriented"], 0);
}

/// The rotation of a smallest-three code: bits 0-1 the index of the largest component, then
/// three 10-bit components in [-1/sqrt 2, 1/sqrt 2]; 0 is the identity.
fn smallest_three(code: u32) -> [f64; 4] {
    if code == 0 {
        return [0.0, 0.0, 0.0, 1.0];
    }
    let largest = (code & 3) as usize;
    let mut q = [0.0f64; 4];
    let mut shift = 2;
    for (i, v) in q.iter_mut().enumerate() {
        if i != largest {
            let bits = (code >> shift) & 0x3ff;
            *v = (f64::from(bits) / 1023.0 * 2.0 - 1.0) / std::f64::consts::SQRT_2;
            shift += 10;
        }
    }
    q[largest] = (1.0 - q.iter().map(|v| v * v).sum::<f64>()).max(0.0).sqrt();
    q
}

#[test]
fn paper_and_shell_maps_keep_within_their_bytes_in_their_versions() {
    let dir = Dir::new("map-v2");
    let bunny = shared("bun000.ply");
    for (name, extra, version, header) in [
        ("paper.mema", "--paper", 1u16, 36usize),
        ("shells.mema", "--model=shells", 2, 48),
    ] {
        let path = dir.join(name);
        MemaCommand::new(&dir)
            .arg("map")
            .arg(&bunny)
            .args(["--bytes", "9600", extra, "-o"])
            .arg(&path)
            .run()
            .assert_ok();
        let bytes = std::fs::read(&path).expect("written");
        assert_eq!(u16_at(&bytes, 4), version, "{name}");
        let count = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
        // At most B bytes of entities, the header and checksum aside, and no fewer than one
        // entity's worth under B.
        let record = (bytes.len() - header - 4) / count;
        assert_eq!(header + record * count + 4, bytes.len(), "{name}");
        assert!(
            record * count <= 9600 && record * (count + 1) > 9600,
            "{name}: {count} x {record}"
        );
        let body = &bytes[..bytes.len() - 4];
        assert_eq!(
            bytes[bytes.len() - 4..],
            crc32fast::hash(body).to_le_bytes()
        );
        let map = HostMap::read(&path).expect("reads back");
        assert_eq!(map.entities.len(), count);
        if version == 1 {
            assert!(map.entities.iter().all(|e| e.entity.rotation.is_identity()));
            continue;
        }
        // Version 2 quantized: decode every record from the documented layout and compare.
        assert_eq!(u16_at(&bytes, 6), 1, "quantized flag");
        let origin = [f64_at(&bytes, 8), f64_at(&bytes, 16), f64_at(&bytes, 24)];
        assert_eq!(origin, map.origin);
        let (step, shortest, log_step) = (
            f64::from(f32_at(&bytes, 36)),
            f64::from(f32_at(&bytes, 40)),
            f64::from(f32_at(&bytes, 44)),
        );
        let mut turned = 0;
        for (i, e) in map.entities.iter().enumerate() {
            let r = &bytes[header + 14 * i..header + 14 * (i + 1)];
            for j in 0..3 {
                let code = i16::from_le_bytes([r[2 * j], r[2 * j + 1]]);
                let c = f64::from(code) * step;
                assert!(
                    (c - f64::from(e.entity.center.to_array()[j])).abs()
                        <= 1e-6 * step.max(c.abs())
                );
            }
            let q = smallest_three(u32::from_le_bytes(r[6..10].try_into().unwrap()));
            let stored = e.entity.rotation.to_array();
            let dot: f64 = (0..4).map(|k| q[k] * f64::from(stored[k])).sum();
            assert!(dot.abs() > 1.0 - 1e-6, "entity {i}: {q:?} vs {stored:?}");
            turned += usize::from(q[3] < 1.0);
            let axes = u32::from_le_bytes(r[10..14].try_into().unwrap());
            assert_eq!(axes & 3, e.kind as u32);
            let semi = e.entity.semi_axes_f64();
            for (j, r) in semi.iter().enumerate() {
                let code = (axes >> (2 + 10 * j)) & 0x3ff;
                if code == 1023 {
                    assert!(r.is_infinite());
                } else {
                    let want = shortest * (log_step * f64::from(code)).exp();
                    assert!(((r - want) / want).abs() < 1e-6, "entity {i} axis {j}");
                }
            }
        }
        assert!(
            turned * 10 > count * 9,
            "shells should be oriented: {turned} of {count}"
        );
    }
}

/// A streamed map whose extent takes a coarse grid and most of whose shells are thinner than
/// four of its steps is written in f32; `mema info` says why, with the count, which is held here
/// to the map's own shells and extent: two patches of a millimetre's relief 2 km apart (3 cm
/// steps), sent in millimetres. Where the wire's own unit is four steps or more, the shells
/// thinner than the grid are thinner than their points' rounding, and the map is quantized:
/// simple.las (4.6 km across, 7 cm steps, sent in 10 m units for its 63 m spacing), and
/// five_people at --working 150, whose single-point frozen shells are as thin but whose steps
/// are under 0.25 mm.
#[test]
fn info_says_why_a_streamed_map_is_not_quantized() {
    let dir = Dir::new("not-quantized");
    let mut patches = String::from("x,y,z\n");
    for x0 in [0.0, 2000.0] {
        for i in 0..60 {
            for j in 0..60 {
                let relief = 0.0005 * f64::from((i * 7 + j * 3) % 5);
                let (x, y) = (x0 + f64::from(i) * 0.01, f64::from(j) * 0.01);
                patches += &format!("{x:.4},{y:.4},{relief:.4}\n");
            }
        }
    }
    let patches = dir.write("patches.csv", patches.as_bytes());
    // `cloud` streamed at the board's working set; `mema info --json` of the map in `out`.
    let streamed_info = |cloud: &std::path::Path, out: &str| {
        MemaCommand::new(&dir)
            .args(["map", &cloud.display().to_string()])
            .args(["-k", "400", "--stream", "--working", "150", "-o", out])
            .run()
            .assert_ok();
        MemaCommand::new(&dir)
            .args(["info", out, "--json"])
            .run()
            .assert_ok()
            .json()
    };
    let info = streamed_info(&patches, "f32.mema");
    assert_eq!(info["layout"], "version 2, oriented f32", "{info}");
    let why = info["not_quantized"].as_str().expect("a reason");
    let map = HostMap::read(&dir.join("f32.mema")).expect("the map");
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for e in &map.entities {
        let c = e.entity.center.to_array();
        for j in 0..3 {
            lo[j] = lo[j].min(c[j]);
            hi[j] = hi[j].max(c[j]);
        }
    }
    let step = (0..3).map(|j| (hi[j] - lo[j]) / 2.0).fold(0.0f32, f32::max) / 32_767.0;
    let thin = map
        .entities
        .iter()
        .filter(|e| e.entity.semi_axes().iter().any(|r| *r < 4.0 * step))
        .count();
    assert!(
        2 * thin > map.entities.len(),
        "{thin} thin of {}",
        map.entities.len()
    );
    assert!(
        why.starts_with(&format!(
            "{thin} of {} shells are thinner",
            map.entities.len()
        )),
        "{why}"
    );
    for cloud in ["simple.las", "five_people.pcd"] {
        let info = streamed_info(&shared(cloud), "quantized.mema");
        assert!(info["not_quantized"].is_null(), "{cloud}: {info}");
        assert_eq!(info["layout"], "version 2, oriented, quantized", "{cloud}");
    }
}

/// docs/map-format.md's precision of the quantized grid, from the grids the code makes: the
/// centre step read from the headers of two maps `mema map` writes, and the semi-axes' worst
/// rounding (half a log step) over 10^4 and over the most the grid spans.
#[test]
fn the_format_guides_precision_is_the_grids() {
    let dir = Dir::new("map-precision");
    let budget = 9_600;
    let step_and_extent = |cloud: &str| {
        MemaCommand::new(&dir)
            .arg("map")
            .arg(shared(cloud))
            .args(["--bytes", &budget.to_string(), "-o", "grid.mema"])
            .run()
            .assert_ok();
        let bytes = std::fs::read(dir.join("grid.mema")).expect("map");
        let info = MemaCommand::new(&dir)
            .args(["info", "grid.mema", "--json"])
            .run()
            .assert_ok()
            .json();
        let across = (0..3)
            .map(|j| {
                info["center_max"][j].as_f64().expect("a bound")
                    - info["center_min"][j].as_f64().expect("a bound")
            })
            .fold(0.0, f64::max);
        (f64::from(f32_at(&bytes, 36)), across)
    };
    let (bunny, _) = step_and_extent("bun_zipper.ply");
    let (sweep, across) = step_and_extent("ouster_os1_0.pcd");
    let worst = |grid: Quantization| 100.0 * (f64::from(grid.axis_log_step) / 2.0).exp_m1();
    let decades = Quantization::for_extent(1.0, 1e-4, 1.0);
    let most = Quantization::for_extent(1.0, 1e-30, 1.0);
    says(
        "docs/map-format.md",
        &format!(
            "(maps at {} bytes): centres are within half a step (a step being the map's half extent / {} around the centre of its entities: {:.1} um \
             on bun_zipper, {:.1} mm on `ouster_os1_0.pcd`, a lidar sweep {across:.0} m across, \
             wherever the world frame puts them), semi-axes within {:.1}% over a range of 10^4 \
             (and {:.1}% over the most the grid spans, 10^{:.0},",
            thousands(budget),
            thousands(i16::MAX as u64),
            bunny * 1e6,
            sweep * 1e3,
            worst(decades),
            worst(most),
            (1.0 / f64::from(most.axis_min)).log10()
        ),
    );
}
