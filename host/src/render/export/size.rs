//! What `mema export` will write, counted from the map before any of it is made: vertices,
//! triangles and bytes, and the limit they are held to.
//!
//! Bytes per vertex and per triangle (V vertices, F triangles, K kinds present):
//! - PLY: its header, then 27 a vertex (three `double`s, three `uchar`s) and 13 a face (a
//!   `uchar` count and three `int`s): exact;
//! - glTF: 12 a vertex (three f32) and 12 a triangle (three u32), the JSON chunk and 28 bytes of
//!   framing: exact but for the accessors' min and max, counted at their longest;
//! - OBJ: text, counted at its longest: 101 bytes a vertex line (coordinates of at most 25
//!   characters, see `formats::obj_number`, and a colour), `5 + 3 digits(V)` a face line.

use serde::Serialize;

use super::formats::{glb_json, obj_header, ply_header};
use super::{MeshFormat, Tessellation};
use crate::error::ConfigError;
use crate::io::mapfile::HostMap;
use mema_core::EntityKind;

/// The most bytes `mema export` writes unless `--max-bytes` says otherwise: 1 GiB, ten
/// times a 100,000-entity map at the default 24 segments and 12 rings in glTF.
pub const DEFAULT_MAX_BYTES: u64 = 1 << 30;

/// The longest OBJ vertex line: `v`, three coordinates of at most 25 characters, three
/// colour channels of 6 (`0.4471`), six spaces and the newline.
pub const OBJ_VERTEX_MAX: u64 = 1 + 3 * 25 + 3 * 6 + 6 + 1;

/// A JSON number glTF's min and max can take at its longest (`-1.17549435e-38`), less the
/// placeholder's `0.0`: the slack each of them gets.
const JSON_NUMBER_SLACK: u64 = 16;

/// The counts and bytes of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MeshSize {
    pub format: MeshFormat,
    pub vertices: u64,
    pub triangles: u64,
    /// The file's size: exact for PLY, at most this for glTF and OBJ.
    pub bytes: u64,
    /// Per kind, in `EntityKind::ALL` order: (vertices, triangles).
    #[serde(skip)]
    pub kinds: [(u64, u64); 4],
}

/// Entities of each kind by their count of infinite axes (0 to 3).
type Shapes = [[u64; 4]; 4];

fn shapes_of(map: &HostMap) -> Shapes {
    let mut n = [[0u64; 4]; 4];
    for e in &map.entities {
        let k = EntityKind::ALL
            .iter()
            .position(|k| *k == e.kind)
            .unwrap_or(0);
        n[k][super::infinite_axes(e).min(3)] += 1;
    }
    n
}

fn digits(n: u64) -> u64 {
    u64::from(n.checked_ilog10().unwrap_or(0)) + 1
}

impl MeshSize {
    /// Counts the export of `map` at `t` in `format`.
    pub fn of(map: &HostMap, t: &Tessellation, format: MeshFormat) -> Self {
        Self::counted(map, &shapes_of(map), t, format)
    }

    fn counted(map: &HostMap, shapes: &Shapes, t: &Tessellation, format: MeshFormat) -> Self {
        let mut kinds = [(0u64, 0u64); 4];
        for (k, of_kind) in shapes.iter().enumerate() {
            for (degenerated, &entities) in of_kind.iter().enumerate() {
                let (v, f) = t.counts(degenerated);
                kinds[k].0 = kinds[k].0.saturating_add(entities.saturating_mul(v as u64));
                kinds[k].1 = kinds[k].1.saturating_add(entities.saturating_mul(f as u64));
            }
        }
        let vertices = kinds.iter().fold(0u64, |a, k| a.saturating_add(k.0));
        let triangles = kinds.iter().fold(0u64, |a, k| a.saturating_add(k.1));
        let present = kinds.iter().filter(|k| k.1 > 0).count() as u64;
        let bytes = match format {
            MeshFormat::Ply => (ply_header(map, vertices, triangles).len() as u64)
                .saturating_add(vertices.saturating_mul(27))
                .saturating_add(triangles.saturating_mul(13)),
            MeshFormat::Obj => {
                let groups: u64 = EntityKind::ALL
                    .iter()
                    .zip(&kinds)
                    .filter(|(_, k)| k.1 > 0)
                    .map(|(kind, _)| 3 + kind.name().len() as u64)
                    .sum();
                (obj_header(map).len() as u64 + groups)
                    .saturating_add(vertices.saturating_mul(OBJ_VERTEX_MAX))
                    .saturating_add(triangles.saturating_mul(5 + 3 * digits(vertices)))
            }
            MeshFormat::Glb => {
                let json = glb_json(map, &kinds, None).map_or(0, |j| j.len() as u64);
                let json = json + 6 * present * JSON_NUMBER_SLACK + 3;
                let bin = vertices.saturating_add(triangles).saturating_mul(12);
                (12 + 8 + 8 + json).saturating_add(bin)
            }
        };
        MeshSize {
            format,
            vertices,
            triangles,
            bytes,
            kinds,
        }
    }

    /// Fails, naming the counts, if the export would pass `max_bytes`, glTF's 4 GiB or the
    /// indices' 31 bits (PLY's `int`).
    pub fn check(
        &self,
        map: &HostMap,
        t: &Tessellation,
        max_bytes: u64,
    ) -> Result<(), ConfigError> {
        if self.vertices > i32::MAX as u64 {
            return Err(ConfigError::TooManyVertices(
                usize::try_from(self.vertices).unwrap_or(usize::MAX),
            ));
        }
        let format = self.format;
        let limit = match format {
            MeshFormat::Glb => max_bytes.min(u64::from(u32::MAX)),
            _ => max_bytes,
        };
        if self.bytes <= limit {
            return Ok(());
        }
        Err(ConfigError::MeshTooLarge {
            entities: map.entities.len(),
            segments: t.segments,
            rings: t.rings,
            vertices: self.vertices,
            triangles: self.triangles,
            bytes: self.bytes,
            format: match format {
                MeshFormat::Ply => "PLY",
                MeshFormat::Obj => "OBJ",
                MeshFormat::Glb => "glTF",
            },
            limit,
            fits: finest_that_fits(map, t, format, limit),
        })
    }
}

/// The most segments, with rings in the same proportion, whose export fits `limit`.
fn finest_that_fits(
    map: &HostMap,
    t: &Tessellation,
    format: MeshFormat,
    limit: u64,
) -> Option<(u32, u32)> {
    let shapes = shapes_of(map);
    let at = |segments: u32| {
        let rings = (f64::from(segments) * f64::from(t.rings) / f64::from(t.segments)).round();
        Tessellation::checked(segments, (rings as u32).clamp(2, 512)).ok()
    };
    let fits = |segments: u32| {
        at(segments).is_some_and(|t| {
            let size = MeshSize::counted(map, &shapes, &t, format);
            size.bytes <= limit && size.vertices <= i32::MAX as u64
        })
    };
    // The bytes grow with the segments, so the last that fits is found by bisection.
    let (mut lo, mut hi) = (3u32, t.segments);
    if !fits(lo) {
        return None;
    }
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        if fits(mid) { lo = mid } else { hi = mid - 1 }
    }
    at(lo).map(|t| (t.segments, t.rings))
}
