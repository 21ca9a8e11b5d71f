//! `mema-firmware-sim`, skeleton: the core driven as firmware drives it, with fixed-size buffers
//! only (no Vec, no Box), on a synthetic capture. The UART stream, fault injection, the f64
//! reference and the Cortex-M4F image come with the firmware issue; this binary already proves the
//! batch path fits in fixed memory and prints the map's bytes as a CRC.

use mema_core::fit::{FitParams, fit_ellipsoid_paper};
use mema_core::kmeans::{CentroidSum, KMeansParams, kmeans};
use mema_core::map::{MapFile, encode, encoded_len};
use mema_core::moments::Moments;
use mema_core::rng::stream_rng;
use mema_core::{Map, MapEntity, Point3};

const POINTS: usize = 512;
const K: usize = 8;

/// Four ellipsoid shells sampled on a Fibonacci lattice: a capture with a known answer.
fn capture() -> [Point3; POINTS] {
    let mut points = [Point3::default(); POINTS];
    let golden = core::f64::consts::PI * (3.0 - 5f64.sqrt());
    for (i, p) in points.iter_mut().enumerate() {
        let shell = (i % 4) as f64;
        let j = (i / 4) as f64;
        let z = 1.0 - 2.0 * (j + 0.5) / (POINTS / 4) as f64;
        let rho = (1.0 - z * z).sqrt();
        let t = golden * j;
        *p = Point3::new(
            (3.0 * shell + 0.4 * rho * t.cos()) as f32,
            (0.25 * rho * t.sin()) as f32,
            (0.15 * z) as f32,
        );
    }
    points
}

/// Builds the map of `points` with every buffer sized at compile time.
fn build_map(points: &[Point3; POINTS], seed: u64) -> Result<Map<K>, &'static str> {
    let mut centres = [Point3::default(); K];
    let mut labels = [0u32; POINTS];
    let mut distances = [0f32; POINTS];
    let mut sums = [CentroidSum::default(); K];
    let params = KMeansParams {
        seed,
        ..KMeansParams::default()
    };
    kmeans(
        points,
        &mut centres,
        &mut labels,
        &mut distances,
        &mut sums,
        &params,
    )
    .map_err(|_| "k-means failed")?;
    let mut moments = [Moments::new(); K];
    for (p, &l) in points.iter().zip(labels.iter()) {
        if let Some(m) = moments.get_mut(l as usize) {
            m.add(*p);
        }
    }
    let fit = FitParams::default();
    let mut map = Map::<K>::new([0.0; 3]);
    for (i, m) in moments.iter().enumerate() {
        let central = m.central().ok_or("empty cluster")?;
        let f = fit_ellipsoid_paper(&central, &fit, &mut stream_rng(seed, 2 * i as u64));
        let kind = f.entity.kind(fit.degeneration.sphere_tolerance);
        map.push(MapEntity {
            entity: f.entity,
            kind,
        })
        .map_err(|_| "map full")?;
    }
    Ok(map)
}

fn main() {
    let points = capture();
    let mut bytes = [0u8; encoded_len(K)];
    let result = build_map(&points, 0).and_then(|map| {
        encode(map.origin, map.entities(), &mut bytes).map_err(|_| "buffer too small")?;
        MapFile::new_checked(&bytes).map_err(|_| "map does not decode")?;
        Ok(map.entities().len())
    });
    match result {
        Ok(n) => {
            let crc = u32::from_le_bytes([
                bytes[bytes.len() - 4],
                bytes[bytes.len() - 3],
                bytes[bytes.len() - 2],
                bytes[bytes.len() - 1],
            ]);
            println!(
                "firmware-sim: {POINTS} points -> {n} entities in {} bytes, CRC-32 {crc:08x}",
                bytes.len()
            );
        }
        Err(e) => {
            eprintln!("mema-firmware-sim: {e}");
            std::process::exit(1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_memory_map_recovers_the_four_shells() {
        let points = capture();
        let map = build_map(&points, 0).expect("map");
        assert_eq!(map.entities().len(), K);
        // Eight clusters over four shells: every entity sits on one shell's axis, x = 3 * shell.
        for e in map.entities() {
            let x = e.entity.center.x / 3.0;
            assert!((x - x.round()).abs() < 0.2, "{:?}", e.entity.center);
        }
        let again = build_map(&points, 0).expect("map");
        assert_eq!(map, again, "same capture and seed, same map");
    }
}
