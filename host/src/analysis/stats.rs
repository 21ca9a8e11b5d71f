//! The paper's tables: Table 2 (memory) and Table 4 (eq. 13 error statistics over clusters).

use serde::Serialize;

/// Bytes per point in the paper's count: three 4-byte floats.
pub const CLOUD_BYTES_PER_POINT: usize = 12;
/// Bytes per entity in the paper's count: six 4-byte floats (centre + semi-axes).
pub const MAP_BYTES_PER_ENTITY: usize = 24;

/// One row of Table 2.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MemoryRow {
    pub points: usize,
    pub cloud_bytes: usize,
    pub entities: usize,
    pub map_bytes: usize,
    pub percent: f64,
}

impl MemoryRow {
    /// The row in the paper's count: 24 bytes an entity.
    pub fn new(points: usize, entities: usize) -> Self {
        Self::with_entity_bytes(points, entities, MAP_BYTES_PER_ENTITY)
    }

    /// The row for a map whose entities take `bytes_per_entity` each (the paper counts 24).
    pub fn with_entity_bytes(points: usize, entities: usize, bytes_per_entity: usize) -> Self {
        let cloud_bytes = points * CLOUD_BYTES_PER_POINT;
        let map_bytes = entities * bytes_per_entity;
        let percent = if cloud_bytes == 0 {
            0.0
        } else {
            100.0 * map_bytes as f64 / cloud_bytes as f64
        };
        Self {
            points,
            cloud_bytes,
            entities,
            map_bytes,
            percent,
        }
    }
}

/// One row of Table 4: statistics of the per-cluster errors `e_i`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorStats {
    pub clusters: usize,
    pub mean: f64,
    /// Population standard deviation (divides by the number of clusters).
    pub std: f64,
    pub max: f64,
    pub min: f64,
    pub total: f64,
}

impl ErrorStats {
    /// Statistics over the non-empty clusters' errors.
    pub fn from_errors(errors: &[f64]) -> Self {
        let n = errors.len();
        if n == 0 {
            return Self {
                clusters: 0,
                mean: 0.0,
                std: 0.0,
                max: 0.0,
                min: 0.0,
                total: 0.0,
            };
        }
        let total: f64 = errors.iter().sum();
        let mean = total / n as f64;
        let var = errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n as f64;
        Self {
            clusters: n,
            mean,
            std: var.sqrt(),
            max: errors.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
            min: errors.iter().cloned().fold(f64::INFINITY, f64::min),
            total,
        }
    }
}

/// One row of Table 2 under [`MEMORY_HEADER`].
pub fn format_memory_row(row: &MemoryRow) -> String {
    format!(
        "{:>10} {:>12} {:>10} {:>10} {:>10.4}%",
        row.points, row.cloud_bytes, row.entities, row.map_bytes, row.percent
    )
}

/// Table 2's column headings.
pub const MEMORY_HEADER: &str = "    points  cloud bytes   entities  map bytes    percent";
/// Table 4's column headings.
pub const ERROR_HEADER: &str =
    "approximation        mean        std        max        min        total";

/// One row of Table 4 under [`ERROR_HEADER`], named `label`.
pub fn format_error_row(label: &str, s: &ErrorStats) -> String {
    format!(
        "{:<13} {:>10.6} {:>10.6} {:>10.6} {:>10.6} {:>12.6}",
        label, s.mean, s.std, s.max, s.min, s.total
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_row_reproduces_the_papers_experiment_1() {
        // Table 2, experiment 1: 10,916 points, 150 ellipsoids, 2.7482%.
        let row = MemoryRow::new(10_916, 150);
        assert_eq!(row.cloud_bytes, 130_992);
        assert_eq!(row.map_bytes, 3600);
        // The paper truncates to four decimals: 2.748259...% prints as 2.7482%.
        assert!((row.percent - 2.7482).abs() < 1e-4);
    }

    #[test]
    fn error_stats_by_hand() {
        let s = ErrorStats::from_errors(&[1.0, 2.0, 3.0, 6.0]);
        assert_eq!(
            (s.clusters, s.total, s.mean, s.max, s.min),
            (4, 12.0, 3.0, 6.0, 1.0)
        );
        assert!((s.std - 3.5f64.sqrt()).abs() < 1e-12);
    }
}
