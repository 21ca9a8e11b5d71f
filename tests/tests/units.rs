//! Units: maps are in metres whatever unit the cloud's file uses. A LAS file's CRS gives its
//! unit (autzen_trim.laz is in international feet), `--units` gives it where the file says
//! nothing, geographic coordinates are refused, and a map in the wrong unit is warned about.

use crate::lidar::raw_points;
use crate::util::{Dir, MemaCommand, shared};
use mema::io::HostMap;
use std::path::{Path, PathBuf};

/// The bunny's vertices as its ASCII PLY writes them (x y z, then confidence and intensity).
fn bunny_vertices() -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(shared("bun_zipper.ply")).expect("bunny");
    let mut lines = text.lines();
    let mut count = 0;
    for line in lines.by_ref() {
        if let Some(n) = line.strip_prefix("element vertex ") {
            count = n.trim().parse().expect("vertex count");
        }
        if line == "end_header" {
            break;
        }
    }
    lines
        .take(count)
        .map(|l| {
            let mut v = l
                .split_whitespace()
                .map(|t| t.parse::<f64>().expect("number"));
            [0; 3].map(|_| v.next().expect("coordinate"))
        })
        .collect()
}

fn write_xyz(dir: &Dir, name: &str, points: &[[f64; 3]], scale: f64) -> PathBuf {
    let text: String = points
        .iter()
        .map(|p| format!("{} {} {}\n", p[0] * scale, p[1] * scale, p[2] * scale))
        .collect();
    dir.write(name, text.as_bytes())
}

fn map(dir: &Dir, cloud: &Path, out: &str, extra: &[&str]) -> MemaCommand {
    MemaCommand::new(dir)
        .arg("map")
        .arg(cloud)
        .args(["-o", out])
        .args(extra)
}

fn bounds(points: impl Iterator<Item = [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    points.fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                [0, 1, 2].map(|j| lo[j].min(p[j])),
                [0, 1, 2].map(|j| hi[j].max(p[j])),
            )
        },
    )
}

/// autzen_trim.laz says in its GeoKeys (and its WKT) that it is in international feet; its
/// map is in metres: the entity centres lie inside the raw LAS coordinates times 0.3048 and
/// span most of them, where a map in feet would lie 3.28 times farther out.
#[test]
fn autzen_is_in_feet_and_its_map_in_metres() {
    let dir = Dir::new("units-autzen");
    let laz = shared("autzen_trim.laz");
    let ran = map(&dir, &laz, "autzen.mema", &["-k", "60", "--json"])
        .run()
        .assert_ok();
    let v = ran.json();
    assert_eq!(v["unit"]["unit"]["name"], "foot", "{v}");
    assert_eq!(v["unit"]["unit"]["metres"], 0.3048);
    assert_eq!(v["unit"]["source"]["file"], "LAS GeoKeys");
    let text = map(&dir, &laz, "autzen2.mema", &["-k", "60"])
        .run()
        .assert_ok();
    assert!(
        text.stdout().contains("unit: foot (LAS GeoKeys)"),
        "{}",
        text.stdout()
    );

    let raw = raw_points(&std::fs::read(&laz).expect("autzen"));
    let (lo, hi) = bounds(raw.iter().map(|p| p.map(|c| c * 0.3048)));
    let map = HostMap::read(&dir.join("autzen.mema")).expect("map");
    let (clo, chi) = bounds(map.entities.iter().map(|e| map.world_center(&e.entity)));
    for j in 0..3 {
        // A centre is a mean of points, so inside their box (a metre for f32 rounding of
        // the local frame and the shells' quantized grid).
        assert!(
            clo[j] >= lo[j] - 1.0 && chi[j] <= hi[j] + 1.0,
            "axis {j}: centres {clo:?}..{chi:?}, cloud in metres {lo:?}..{hi:?}"
        );
    }
    for j in 0..2 {
        assert!(
            chi[j] - clo[j] > 0.7 * (hi[j] - lo[j]),
            "axis {j}: centres {clo:?}..{chi:?} span too little of {lo:?}..{hi:?}"
        );
    }

    // eval reads the cloud the same way, so the map and its cloud agree: points lie within
    // metres of the surfaces (in feet, against a map in metres, they would be kilometres off).
    let eval = MemaCommand::new(&dir)
        .arg("eval")
        .arg(&laz)
        .arg(dir.join("autzen.mema"))
        .arg("--json")
        .run()
        .assert_ok()
        .json();
    assert_eq!(eval["unit"]["unit"]["name"], "foot");
    let accuracy = eval["accuracy"]["mean"].as_f64().expect("accuracy");
    assert!(accuracy < 2.0, "accuracy mean {accuracy} m");
}

/// The bunny written in millimetres maps with `--units mm` to the bunny's map in metres:
/// same entities, kinds and centres. Without `--units`, the paper's model degenerates most
/// entities (the 4 m threshold is 4 mm of bunny) and says so.
#[test]
fn a_millimetre_bunny_with_units_mm_is_the_metre_bunny() {
    let dir = Dir::new("units-bunny");
    let vertices = bunny_vertices();
    assert_eq!(vertices.len(), 35_947);
    let metres = write_xyz(&dir, "bun_m.xyz", &vertices, 1.0);
    let millimetres = write_xyz(&dir, "bun_mm.xyz", &vertices, 1000.0);
    for model in ["paper", "shells"] {
        let args = ["-k", "100", "--json", "--model", model];
        let m = map(&dir, &metres, "m.mema", &args).run().assert_ok().json();
        let mut mm_args = args.to_vec();
        mm_args.extend(["--units", "mm"]);
        let mm = map(&dir, &millimetres, "mm.mema", &mm_args)
            .run()
            .assert_ok()
            .json();
        assert_eq!(m["unit"]["source"], "assumed", "{m}");
        assert_eq!(mm["unit"]["unit"]["name"], "millimetre", "{mm}");
        assert_eq!(mm["unit"]["source"], "given");
        assert_eq!(m["kinds"], mm["kinds"], "{model}");
        assert_eq!(m["memory"], mm["memory"], "{model}");
        let (a, b) = (
            HostMap::read(&dir.join("m.mema")).expect("map"),
            HostMap::read(&dir.join("mm.mema")).expect("map"),
        );
        assert_eq!(a.entities.len(), b.entities.len());
        for (i, (ea, eb)) in a.entities.iter().zip(&b.entities).enumerate() {
            let (ca, cb) = (a.world_center(&ea.entity), b.world_center(&eb.entity));
            for j in 0..3 {
                assert!(
                    (ca[j] - cb[j]).abs() < 1e-6,
                    "{model} entity {i}: {ca:?} vs {cb:?}"
                );
            }
        }
        let em = m["ellipsoidal"]["mean"].as_f64().expect("mean");
        let emm = mm["ellipsoidal"]["mean"].as_f64().expect("mean");
        assert!((em - emm).abs() <= 1e-6 * em, "{model}: {em} vs {emm}");
    }

    let wrong = map(&dir, &millimetres, "wrong.mema", &["-k", "100", "--paper"])
        .run()
        .assert_ok();
    let err = wrong.stderr();
    assert!(
        err.contains("warning") && err.contains("degenerated") && err.contains("--units"),
        "{err}"
    );
    assert!(
        wrong
            .stdout()
            .contains("unit: metre (assumed; --units to change)"),
        "{}",
        wrong.stdout()
    );
    // The bunny in metres maps without the warning.
    let right = map(&dir, &metres, "right.mema", &["-k", "100", "--paper"])
        .run()
        .assert_ok();
    assert!(!right.stderr().contains("warning"), "{}", right.stderr());
}

/// simple.las with one VLR more, inserted before its point data.
fn with_vlr(record: u16, data: &[u8]) -> Vec<u8> {
    let b = std::fs::read(shared("simple.las")).expect("simple.las");
    let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    let (data_at, vlrs) = (u32_at(96) as usize, u32_at(100));
    let mut vlr = vec![0u8; 2];
    vlr.extend_from_slice(b"LASF_Projection\0");
    vlr.extend_from_slice(&record.to_le_bytes());
    vlr.extend_from_slice(&(data.len() as u16).to_le_bytes());
    vlr.extend_from_slice(&[0u8; 32]);
    vlr.extend_from_slice(data);
    let mut out = b[..data_at].to_vec();
    out[96..100].copy_from_slice(&((data_at + vlr.len()) as u32).to_le_bytes());
    out[100..104].copy_from_slice(&(vlrs + 1).to_le_bytes());
    out.extend_from_slice(&vlr);
    out.extend_from_slice(&b[data_at..]);
    out
}

fn geokeys(keys: &[[u16; 4]]) -> Vec<u8> {
    let mut shorts = vec![1, 1, 0, keys.len() as u16];
    shorts.extend(keys.iter().flatten());
    shorts.iter().flat_map(|s| s.to_le_bytes()).collect()
}

/// Longitude and latitude in degrees are no lengths: a LAS file whose GeoKeys or WKT say so is
/// refused with what to do; `--units` overrides it for a user who knows better.
#[test]
fn geographic_las_is_refused_for_mapping() {
    let dir = Dir::new("units-geographic");
    let degrees = geokeys(&[[1024, 0, 1, 2], [2054, 0, 1, 9102]]);
    let wkt = br#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
    for (name, bytes) in [
        ("geokeys.las", with_vlr(34735, &degrees)),
        ("wkt.las", with_vlr(2112, wkt)),
    ] {
        let path = dir.write(name, &bytes);
        for needle in ["geographic", "reproject", "--units"] {
            map(&dir, &path, "out.mema", &["-k", "10"])
                .run()
                .assert_error(1, needle);
        }
        assert!(!dir.join("out.mema").exists());
        MemaCommand::new(&dir)
            .arg("eval")
            .arg(&path)
            .arg(dir.join("none.mema"))
            .run()
            .assert_error(1, "geographic");
        let forced = map(&dir, &path, "forced.mema", &["-k", "10", "--units", "m"])
            .run()
            .assert_ok();
        assert!(forced.stderr().contains("overrides"), "{}", forced.stderr());
        assert!(forced.stdout().contains("unit: metre (--units)"));
        std::fs::remove_file(dir.join("forced.mema")).expect("forced map written");
    }
}

/// US survey feet in the GeoKeys scale the map by 1200/3937 against the same file without a
/// CRS, which is taken as metres.
#[test]
fn us_survey_feet_from_geokeys() {
    let dir = Dir::new("units-usft");
    let plain = shared("simple.las");
    let usft = dir.write(
        "usft.las",
        &with_vlr(34735, &geokeys(&[[1024, 0, 1, 1], [3076, 0, 1, 9003]])),
    );
    let a = map(&dir, &plain, "plain.mema", &["-k", "10", "--json"])
        .run()
        .assert_ok()
        .json();
    let b = map(&dir, &usft, "usft.mema", &["-k", "10", "--json"])
        .run()
        .assert_ok()
        .json();
    assert_eq!(a["unit"]["source"], "assumed");
    assert_eq!(b["unit"]["unit"]["name"], "US survey foot", "{b}");
    let (a, b) = (
        HostMap::read(&dir.join("plain.mema")).expect("map"),
        HostMap::read(&dir.join("usft.mema")).expect("map"),
    );
    for j in 0..3 {
        let want = a.origin[j] * 1200.0 / 3937.0;
        assert!(
            (b.origin[j] - want).abs() <= 1e-9 * want.abs().max(1.0),
            "{:?} vs {:?}",
            b.origin,
            a.origin
        );
    }
}

#[test]
fn a_bogus_unit_is_a_usage_error() {
    let dir = Dir::new("units-bogus");
    let ran = map(
        &dir,
        &shared("bun_zipper.ply"),
        "out.mema",
        &["-k", "10", "--units", "furlong"],
    )
    .run();
    assert_eq!(ran.output.status.code(), Some(2), "{}", ran.stderr());
    assert!(ran.stderr().contains("furlong") && ran.stderr().contains("us-ft"));
    assert!(!dir.join("out.mema").exists());
}
