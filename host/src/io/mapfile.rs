//! Map files: `.mema` (binary, see `mema_core::map`), `.csv` and `.json`, written atomically.

use anyhow::{Context, Result, bail};
use mema_core::map::record::Quantization;
use mema_core::map::{Layout, MapFile, encode_pieces_with};

use crate::io::free_space::{self, FreeImage};
use mema_core::{Entity, EntityKind, MapEntity, Point3, Rotation};
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::error::ConfigError;
pub use crate::io::atomic::write_file_atomically;

/// A map on the host: the local frame's origin (f64, the cloud's own coordinates) and entities.
///
/// Written and read in the format of the path's extension. `.mema` and JSON keep every bit, so
/// a map read back equals the map written; CSV holds world coordinates, around an origin of its
/// own:
///
/// ```
/// use mema::io::HostMap;
/// use mema_core::{Entity, MapEntity, Point3};
///
/// let sphere = Entity::sphere(Point3::new(0.5, 0.0, -1.0), 0.25);
/// let entity = MapEntity { entity: sphere, kind: sphere.kind(0.01) };
/// let map = HostMap::new([651_000.0, 4_912_000.0, 120.0], vec![entity]);
/// let dir = std::env::temp_dir().join(format!("mema-doc-map-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// for name in ["m.mema", "m.json"] {
///     map.write(&dir.join(name))?;
///     assert_eq!(HostMap::read(&dir.join(name))?, map, "{name}");
/// }
/// map.write(&dir.join("m.csv"))?;
/// let csv = HostMap::read(&dir.join("m.csv"))?;
/// assert_eq!(csv.world_center(&csv.entities[0].entity), map.world_center(&sphere));
/// assert!(HostMap::read(&dir.join("m.txt")).is_err());
/// # std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), anyhow::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct HostMap {
    /// The local frame's origin, in the cloud's own coordinates.
    pub origin: [f64; 3],
    /// The entities, in the local frame.
    pub entities: Vec<MapEntity>,
    /// The grid of a quantized map: its `.mema` file is written on it (14 bytes an entity).
    /// `None` writes f32 records, version 1 when every entity is axis-aligned.
    pub quantization: Option<Quantization>,
    /// The range images of the scans the map was made from (empty: no free space recorded),
    /// in the map file's free-space part.
    pub free_space: Vec<FreeImage>,
}

/// The map file formats, chosen by a path's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapFormat {
    Mema,
    Csv,
    Json,
}

impl MapFormat {
    /// The format of a map path's extension (`.mema`, `.csv`, `.json`, any case).
    pub fn from_path(path: &Path) -> Result<Self, ConfigError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("mema") => Ok(Self::Mema),
            Some("csv") => Ok(Self::Csv),
            Some("json") => Ok(Self::Json),
            _ => Err(ConfigError::MapExtension(path.to_path_buf())),
        }
    }
}

impl MapFormat {
    /// Whether a file can be a map of this format from its first bytes: a `.mema` file starts
    /// with its magic, a JSON map with `{` (after spaces), a CSV map with ASCII text.
    fn start_check(self) -> crate::io::input::StartCheck {
        match self {
            Self::Mema => |start| {
                let magic = &mema_core::map::MAGIC;
                if magic.starts_with(start) || start.starts_with(magic) {
                    Ok(())
                } else {
                    Err(format!(
                        "it starts with {start:02x?}, a .mema map with {magic:02x?} (\"MEMA\")"
                    ))
                }
            },
            Self::Json => |start| match start.iter().find(|b| !b.is_ascii_whitespace()) {
                None | Some(b'{') => Ok(()),
                Some(b) => Err(format!(
                    "a JSON map starts with '{{', this with byte {b:#04x}"
                )),
            },
            Self::Csv => |start| match start
                .iter()
                .find(|&&b| !(b.is_ascii_graphic() || b.is_ascii_whitespace()))
            {
                None => Ok(()),
                Some(b) => Err(format!(
                    "a CSV map is ASCII text, this starts with byte {b:#04x}"
                )),
            },
        }
    }
}

/// Entities per kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct KindCounts {
    pub ellipsoid: usize,
    pub sphere: usize,
    pub pseudocylinder: usize,
    pub plane_pair: usize,
}

impl KindCounts {
    /// Counts `map`'s entities by kind.
    pub fn of(map: &HostMap) -> Self {
        let count = |k: EntityKind| map.entities.iter().filter(|e| e.kind == k).count();
        Self {
            ellipsoid: count(EntityKind::Ellipsoid),
            sphere: count(EntityKind::Sphere),
            pseudocylinder: count(EntityKind::Pseudocylinder),
            plane_pair: count(EntityKind::PlanePair),
        }
    }
}

/// The largest map file read: 1 GiB is 76 million quantized entities, far past any map the
/// pipeline makes; `mema info` on a link to /dev/zero used to read until memory ran out.
pub const MAP_LIMIT: u64 = 1 << 30;

impl HostMap {
    /// Centre of entity `i` in the cloud's own coordinates.
    pub fn world_center(&self, e: &Entity) -> [f64; 3] {
        let c = e.center.to_f64();
        [
            self.origin[0] + c[0],
            self.origin[1] + c[1],
            self.origin[2] + c[2],
        ]
    }

    /// A map of f32 entities (not quantized).
    pub fn new(origin: [f64; 3], entities: Vec<MapEntity>) -> Self {
        Self {
            origin,
            entities,
            quantization: None,
            free_space: Vec::new(),
        }
    }

    /// The `.mema` layout this map is written in.
    pub fn layout(&self) -> Layout {
        match self.quantization {
            Some(grid) => Layout::Quantized(grid),
            // Version 1 has no free-space part.
            None if self.free_space.is_empty()
                && self
                    .entities
                    .iter()
                    .all(|e| e.entity.rotation.is_identity()) =>
            {
                Layout::AxisAligned
            }
            None => Layout::Oriented,
        }
    }

    /// The `.mema` bytes of the map, in its [`layout`](Self::layout).
    pub fn to_mema(&self) -> Result<Vec<u8>> {
        let layout = self.layout();
        let mut out = Vec::with_capacity(
            layout.encoded_len(self.entities.len()) + free_space::part_bytes(&self.free_space),
        );
        encode_pieces_with(
            layout,
            self.origin,
            self.entities.iter().copied(),
            self.free_space
                .iter()
                .map(|i| (i.geometry, i.cells.as_slice())),
            |piece| out.extend_from_slice(piece),
        )
        .map_err(anyhow::Error::from)?;
        Ok(out)
    }

    /// The CSV text of the map: a header line, then one entity a line in world coordinates.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind\n");
        for e in &self.entities {
            let c = self.world_center(&e.entity);
            let r = e.entity.semi_axes();
            let q = e.entity.rotation.to_array();
            // Shortest round-trip formatting, and `inf` for a degenerated axis.
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{}\n",
                c[0],
                c[1],
                c[2],
                r[0],
                r[1],
                r[2],
                q[0],
                q[1],
                q[2],
                q[3],
                e.kind.name()
            ));
        }
        s
    }

    /// The JSON text of the map (`"format": "mema-map"`).
    pub fn to_json(&self) -> Result<String> {
        let doc = JsonMap {
            format: "mema-map".into(),
            version: mema_core::map::VERSION,
            origin: self.origin,
            entities: self
                .entities
                .iter()
                .map(|e| JsonEntity {
                    center: self.world_center(&e.entity),
                    local_center: e.entity.center.to_array(),
                    weights: e.entity.weights,
                    rotation: e.entity.rotation.to_array(),
                    semi_axes: e.entity.semi_axes().map(|r| r.is_finite().then_some(r)),
                    kind: e.kind.name().into(),
                })
                .collect(),
        };
        Ok(serde_json::to_string_pretty(&doc)? + "\n")
    }

    /// The map's bytes in `format`.
    pub fn encode_as(&self, format: MapFormat) -> Result<Vec<u8>> {
        Ok(match format {
            MapFormat::Mema => self.to_mema()?,
            MapFormat::Csv => self.to_csv().into_bytes(),
            MapFormat::Json => self.to_json()?.into_bytes(),
        })
    }

    /// Writes the map in the format of `path`'s extension, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let bytes = self.encode_as(MapFormat::from_path(path)?)?;
        write_atomically(path, &bytes)
    }

    /// Reads a map file in the format of its extension.
    /// Reads a map of at most [`MAP_LIMIT`] bytes (a pipe or a device included, within
    /// `io::input`'s idle timeout).
    pub fn read(path: &Path) -> Result<Self> {
        let format = MapFormat::from_path(path)?;
        let bytes =
            crate::io::input::read_bounded_as(path, MAP_LIMIT, "map", format.start_check())?;
        let parsed = match format {
            MapFormat::Mema => Self::from_mema(&bytes),
            MapFormat::Csv => Self::from_csv(&String::from_utf8_lossy(&bytes)),
            MapFormat::Json => Self::from_json(&bytes),
        };
        parsed.with_context(|| format!("{}", path.display()))
    }

    /// Decodes `.mema` bytes (any version), checking their CRC.
    pub fn from_mema(bytes: &[u8]) -> Result<Self> {
        let file = MapFile::new_checked(bytes).map_err(anyhow::Error::from)?;
        Ok(Self {
            origin: file.origin(),
            entities: file.entities().collect(),
            quantization: match file.layout() {
                Layout::Quantized(grid) => Some(grid),
                _ => None,
            },
            free_space: file
                .free_space()
                .map(|(geometry, cells)| FreeImage {
                    geometry,
                    cells: cells.to_vec(),
                })
                .collect(),
        })
    }

    fn from_world(rows: Vec<CsvRow>) -> Result<Self> {
        // A local origin at the centres' mean keeps georeferenced centres precise in f32.
        let n = rows.len().max(1) as f64;
        let mut origin = [0.0; 3];
        for (_, c, ..) in &rows {
            for j in 0..3 {
                origin[j] += c[j] / n;
            }
        }
        let mut entities = Vec::with_capacity(rows.len());
        for (line, c, r, rotation, kind) in rows {
            let local = [0, 1, 2].map(|j| (c[j] - origin[j]) as f32);
            if !local.iter().all(|v| v.is_finite()) {
                bail!(
                    "line {line}: centre {c:?} is too far from the map's other centres for f32 (the binary map's precision)"
                );
            }
            let weights = r.map(|r| {
                if r.is_finite() {
                    (1.0 / (r * r)) as f32
                } else {
                    0.0
                }
            });
            if !weights.iter().all(|w| w.is_finite()) {
                bail!(
                    "line {line}: semi-axes {r:?} include one too short for f32 (1/r^2 overflows)"
                );
            }
            entities.push(MapEntity {
                entity: Entity {
                    center: Point3::new(local[0], local[1], local[2]),
                    weights,
                    rotation,
                },
                kind,
            });
        }
        Ok(Self::new(origin, entities))
    }

    fn from_csv(text: &str) -> Result<Self> {
        if text.trim().is_empty() {
            bail!("an empty file, not a mema CSV map (header cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind)");
        }
        let mut rows = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || (i == 0 && line.starts_with("cx")) {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            // Version 1's seven columns are an axis-aligned map.
            let (cx, cy, cz, rx, ry, rz, q, kind) = match fields[..] {
                [cx, cy, cz, rx, ry, rz, qx, qy, qz, qw, kind] => {
                    (cx, cy, cz, rx, ry, rz, Some([qx, qy, qz, qw]), kind)
                }
                [cx, cy, cz, rx, ry, rz, kind] => (cx, cy, cz, rx, ry, rz, None, kind),
                _ => bail!(
                    "line {}: expected cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind (or cx,cy,cz,rx,ry,rz,kind)",
                    i + 1
                ),
            };
            let num = |s: &str| -> Result<f64> {
                let v: f64 = s
                    .parse()
                    .with_context(|| format!("line {}: '{s}' is not a number", i + 1))?;
                if v.is_nan() {
                    bail!("line {}: NaN in a map", i + 1);
                }
                Ok(v)
            };
            let c = [num(cx)?, num(cy)?, num(cz)?];
            let r = [num(rx)?, num(ry)?, num(rz)?];
            if c.iter().any(|v| !v.is_finite()) || r.iter().any(|&v| v <= 0.0) {
                bail!(
                    "line {}: centre must be finite and semi-axes positive",
                    i + 1
                );
            }
            let rotation = match q {
                Some(q) => unit_rotation([num(q[0])?, num(q[1])?, num(q[2])?, num(q[3])?])
                    .with_context(|| format!("line {}", i + 1))?,
                None => Rotation::IDENTITY,
            };
            let kind = EntityKind::from_name(kind)
                .with_context(|| format!("line {}: unknown kind '{kind}'", i + 1))?;
            rows.push((i + 1, c, r, rotation, kind));
        }
        Self::from_world(rows)
    }

    fn from_json(bytes: &[u8]) -> Result<Self> {
        let doc: JsonMap = serde_json::from_slice(bytes).context("not a mema JSON map")?;
        if doc.format != "mema-map" {
            bail!("format is '{}', not 'mema-map'", doc.format);
        }
        if !(1..=mema_core::map::VERSION).contains(&doc.version) {
            bail!(
                "map version {} is not supported (this build reads 1 to {})",
                doc.version,
                mema_core::map::VERSION
            );
        }
        let mut entities = Vec::with_capacity(doc.entities.len());
        for (i, e) in doc.entities.iter().enumerate() {
            let kind = EntityKind::from_name(&e.kind)
                .with_context(|| format!("entity {i}: unknown kind '{}'", e.kind))?;
            let rotation =
                unit_rotation(e.rotation.map(f64::from)).with_context(|| format!("entity {i}"))?;
            let entity = Entity {
                center: Point3::from(e.local_center),
                weights: e.weights,
                rotation,
            };
            if !entity.center.is_finite()
                || entity.weights.iter().any(|w| !(w.is_finite() && *w >= 0.0))
            {
                bail!("entity {i}: invalid centre or weights");
            }
            entities.push(MapEntity { entity, kind });
        }
        Ok(Self::new(doc.origin, entities))
    }
}

/// (line, world centre, semi-axes, rotation, kind) of one CSV row.
type CsvRow = (usize, [f64; 3], [f64; 3], Rotation, EntityKind);

/// A rotation from a text map's quaternion, which must be of unit length within 1e-3 (a
/// quaternion printed to six or more digits): anything else is a mistake, not a rotation.
fn unit_rotation(q: [f64; 4]) -> Result<Rotation> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > 1e-3 || norm.is_nan() {
        bail!("quaternion {q:?} has length {norm}, not 1");
    }
    Rotation::from_quaternion(q).context("quaternion is not a rotation")
}

#[derive(Serialize, Deserialize)]
struct JsonMap {
    format: String,
    version: u16,
    origin: [f64; 3],
    entities: Vec<JsonEntity>,
}

#[derive(Serialize, Deserialize)]
struct JsonEntity {
    /// World coordinates (origin + local centre).
    center: [f64; 3],
    /// The stored f32 centre in the map's local frame.
    local_center: [f32; 3],
    /// `1 / r^2`, 0 for a degenerated axis: the exact stored values.
    weights: [f32; 3],
    /// Unit quaternion `[x, y, z, w]`, `x_world = center + R(q) x_local`; absent in version 1.
    #[serde(default = "identity_quaternion")]
    rotation: [f32; 4],
    /// `null` for a degenerated (infinite) axis.
    semi_axes: [Option<f32>; 3],
    kind: String,
}

fn identity_quaternion() -> [f32; 4] {
    Rotation::IDENTITY.to_array()
}

/// Writes a map to `path` atomically ([`write_file_atomically`]).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_file_atomically(path, bytes, "map")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> HostMap {
        let mut entities = Vec::new();
        for (i, kind) in EntityKind::ALL.into_iter().enumerate() {
            let r = [
                0.5 + i as f64,
                0.25,
                if i >= 2 { f64::INFINITY } else { 0.75 },
            ];
            let weights = r.map(|r| {
                if r.is_finite() {
                    (1.0 / (r * r)) as f32
                } else {
                    0.0
                }
            });
            entities.push(MapEntity {
                entity: Entity::axis_aligned(Point3::new(i as f32, -1.5, 0.25), weights),
                kind,
            });
        }
        HostMap::new([631_000.5, 4_833_000.25, 120.0], entities)
    }

    #[test]
    fn all_formats_round_trip() {
        let map = sample();
        let bytes = map.to_mema().expect("encode");
        assert_eq!(HostMap::from_mema(&bytes).expect("decode"), map);
        // The trailer is the standard CRC-32, as an independent implementation computes it.
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        assert_eq!(crc, crc32fast::hash(body).to_le_bytes());
        assert_eq!(
            HostMap::from_json(map.to_json().expect("json").as_bytes()).expect("decode"),
            map
        );
        let csv = HostMap::from_csv(&map.to_csv()).expect("csv");
        assert!(map.to_csv().lines().nth(3).expect("row").contains("inf"));
        for (a, b) in csv.entities.iter().zip(map.entities.iter()) {
            assert_eq!(a.kind, b.kind);
            let (wa, wb) = (csv.world_center(&a.entity), map.world_center(&b.entity));
            for j in 0..3 {
                assert!((wa[j] - wb[j]).abs() < 1e-6);
                assert!(
                    (a.entity.weights[j] - b.entity.weights[j]).abs() <= 1e-6 * b.entity.weights[j]
                );
            }
        }
    }

    #[test]
    fn text_maps_refuse_what_the_binary_map_cannot_hold() {
        let header = "cx,cy,cz,rx,ry,rz,qx,qy,qz,qw,kind\n";
        for (body, needle) in [
            ("", "empty file"),
            ("  \n\n", "empty file"),
            // 1e-30 would be an infinite weight.
            ("0,0,0,1e-30,1,1,0,0,0,1,ellipsoid\n", "too short"),
            // Two centres 1e300 apart cannot both be f32 around one origin.
            (
                "1e300,0,0,1,1,1,0,0,0,1,ellipsoid\n-1e300,0,0,1,1,1,0,0,0,1,ellipsoid\n",
                "too far",
            ),
            ("0,0,0,1,1,1,0,0,0,2,ellipsoid\n", "length"),
            ("0,0,0,1,1,1,0,0,0,1,blob\n", "unknown kind"),
        ] {
            let text = if body.trim().is_empty() {
                body.to_string()
            } else {
                format!("{header}{body}")
            };
            let err = HostMap::from_csv(&text).expect_err(needle);
            assert!(format!("{err:#}").contains(needle), "{needle}: {err:#}");
        }
        // A header alone is a map with no entities, as mema writes an empty map.
        assert!(
            HostMap::from_csv(header)
                .expect("header only")
                .entities
                .is_empty()
        );
        for (json, needle) in [
            (
                r#"{"format":"other","version":2,"origin":[0,0,0],"entities":[]}"#,
                "not 'mema-map'",
            ),
            (
                r#"{"format":"mema-map","version":3,"origin":[0,0,0],"entities":[]}"#,
                "version 3",
            ),
        ] {
            let err = HostMap::from_json(json.as_bytes()).expect_err(needle);
            assert!(format!("{err:#}").contains(needle), "{needle}: {err:#}");
        }
    }

    #[test]
    fn temporaries_of_dead_writers_are_removed_and_live_ones_kept() {
        let dir = std::env::temp_dir().join(format!("mema-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        // PID 4194304 is past Linux's largest (2^22), so no process has it; PID 1 always runs.
        let dead = dir.join(".m.mema.4194304.tmp");
        let live = dir.join(".m.mema.1.tmp");
        let other = dir.join(".n.mema.4194304.tmp");
        for p in [&dead, &live, &other] {
            std::fs::write(p, b"partial").expect("temp");
        }
        sample().write(&dir.join("m.mema")).expect("write");
        assert!(!dead.exists(), "a dead writer's temporary is removed");
        assert!(live.exists(), "a live writer's temporary is kept");
        assert!(other.exists(), "another file's temporary is not touched");
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn atomic_write_leaves_no_temp_and_fails_cleanly() {
        let dir = std::env::temp_dir().join(format!("mema-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("m.mema");
        sample().write(&path).expect("write");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("m.mema")]);
        let err = sample()
            .write(&dir.join("missing/m.mema"))
            .expect_err("no such dir");
        assert!(format!("{err:#}").contains("cannot write map"), "{err:#}");
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
