//! The default model: each k-means cluster becomes the oriented shell of its covariance
//! (`mema_core::shell`), and the map is stored quantized (14 bytes an entity), so a byte budget
//! buys about 1.8 times the paper's entities and each one follows its surface's tilt.

use mema_core::map::record::{QUANTIZED_LEN, Quantization};
use mema_core::shell::{ShellParams, shell};
use mema_core::{MapEntity, Point3};
use rayon::prelude::*;

use super::pipeline::Members;
use crate::io::mapfile::HostMap;

/// Bytes of one entity of the shell model's file (the header and checksum aside).
pub const BYTES_PER_ENTITY: usize = QUANTIZED_LEN;

/// A cluster's mean and covariance.
pub type MeanCovariance = ([f64; 3], [[f64; 3]; 3]);

/// Mean and covariance of each cluster's points (f64, summed about the cluster's k-means
/// centre so the second moments do not cancel), its points in point order.
pub fn cluster_covariances(
    points: &[Point3],
    labels: &[u32],
    centres: &[Point3],
) -> Vec<Option<MeanCovariance>> {
    let members = Members::of(labels, centres.len());
    centres
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let c = c.to_f64();
            let of = members.of_cluster(i);
            if of.is_empty() {
                return None;
            }
            let mut sum = [0.0f64; 3];
            let mut cross = [[0.0f64; 3]; 3];
            for &p in of {
                let q = points[p as usize].to_f64();
                let d = [q[0] - c[0], q[1] - c[1], q[2] - c[2]];
                for a in 0..3 {
                    sum[a] += d[a];
                    for b in 0..3 {
                        cross[a][b] += d[a] * d[b];
                    }
                }
            }
            let n = of.len() as f64;
            let mean_offset = sum.map(|s| s / n);
            let mut cov = [[0.0; 3]; 3];
            for a in 0..3 {
                for b in 0..3 {
                    cov[a][b] = cross[a][b] / n - mean_offset[a] * mean_offset[b];
                }
            }
            let mean = [0, 1, 2].map(|j| c[j] + mean_offset[j]);
            Some((mean, cov))
        })
        .collect()
}

/// The shells of the clusters, on the grid they will be stored on: the map in memory is
/// exactly the map its file reads back. Empty clusters have no entity.
pub fn shell_map(
    origin: [f64; 3],
    points: &[Point3],
    labels: &[u32],
    centres: &[Point3],
    params: &ShellParams,
) -> HostMap {
    let tolerance = params.degeneration.sphere_tolerance;
    let entities: Vec<MapEntity> = cluster_covariances(points, labels, centres)
        .into_iter()
        .filter_map(|c| c.and_then(|(mean, cov)| shell(mean, cov, params)))
        .map(|entity| MapEntity {
            entity,
            kind: entity.kind(tolerance),
        })
        .collect();
    let grid = Quantization::for_entities(entities.iter().copied());
    HostMap {
        origin,
        entities: entities.into_iter().map(|e| grid.quantize(e)).collect(),
        quantization: Some(grid),
        free_space: Vec::new(),
    }
}
