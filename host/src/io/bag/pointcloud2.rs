//! `sensor_msgs/msg/PointCloud2`: the message, and its x, y, z whatever the field layout.
//!
//! The message, in CDR order: `header` (stamp, frame_id), `height`, `width` (u32), `fields`
//! (a sequence of `PointField`: name, offset u32, datatype u8, count u32), `is_bigendian`
//! (bool), `point_step`, `row_step` (u32), `data` (`sequence<uint8>`), `is_dense` (bool).
//!
//! A point is `point_step` bytes; row `r`'s point `c` starts at `r * row_step + c * point_step`
//! of `data`. Its x, y and z are the fields of those names, of any of the eight datatypes
//! (INT8 = 1, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = 8), at any offset within
//! the point, in the byte order `is_bigendian` gives (which is the data's, not the CDR's). The
//! other fields (intensity, rgb, ring, time...) are skipped. The layout is checked once, before
//! any point is read, so that every point read stays inside `data`.

use super::cdr::{Cdr, CdrError, Header};
use crate::io::read::{Endian, Scalar};

/// One `sensor_msgs/msg/PointField`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

/// A decoded `PointCloud2`, its data borrowed from the message.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud2<'a> {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: &'a [u8],
    pub is_dense: bool,
}

/// The fewest bytes a `PointField` takes: an empty name's length, offset, datatype, count.
const LEAST_FIELD: usize = 4 + 4 + 1 + 4;

/// Why a `PointCloud2`'s layout gives no points.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// No field named x, y or z.
    #[error("no field `{axis}` (fields: {fields})")]
    MissingAxis { axis: &'static str, fields: String },
    /// A datatype outside 1..=8.
    #[error("field `{axis}` has datatype {datatype}, not one of 1..=8 (INT8 to FLOAT64)")]
    Datatype { axis: &'static str, datatype: u8 },
    /// A coordinate reaching past its point.
    #[error(
        "field `{axis}` at offset {offset} ({size} bytes) reaches past point_step {point_step}"
    )]
    PastPoint {
        axis: &'static str,
        offset: u32,
        size: usize,
        point_step: u32,
    },
    /// Rows overlapping: `row_step` shorter than a row's points.
    #[error("row_step {row_step} is shorter than width {width} x point_step {point_step}")]
    RowStep {
        row_step: u32,
        width: u32,
        point_step: u32,
    },
    /// `data` shorter than the points the header declares.
    #[error(
        "{height} x {width} points of point_step {point_step}, row_step {row_step} need {need} bytes of data, it has {have}"
    )]
    ShortData {
        height: u32,
        width: u32,
        point_step: u32,
        row_step: u32,
        need: u64,
        have: usize,
    },
}

impl<'a> PointCloud2<'a> {
    /// Decodes the CDR bytes of one message.
    pub fn parse(message: &'a [u8]) -> Result<Self, CdrError> {
        let mut c = Cdr::new(message)?;
        let header = c.header()?;
        let height = c.u32("height")?;
        let width = c.u32("width")?;
        let n = c.count(LEAST_FIELD, "fields")?;
        let mut fields = Vec::with_capacity(n);
        for _ in 0..n {
            fields.push(PointField {
                name: c.string("fields[].name")?.to_owned(),
                offset: c.u32("fields[].offset")?,
                datatype: c.u8("fields[].datatype")?,
                count: c.u32("fields[].count")?,
            });
        }
        let is_bigendian = c.bool("is_bigendian")?;
        let point_step = c.u32("point_step")?;
        let row_step = c.u32("row_step")?;
        let data = c.bytes("data")?;
        let is_dense = c.bool("is_dense")?;
        Ok(Self {
            header,
            height,
            width,
            fields,
            is_bigendian,
            point_step,
            row_step,
            data,
            is_dense,
        })
    }

    /// Points the header declares: height x width.
    pub fn slots(&self) -> u64 {
        u64::from(self.height) * u64::from(self.width)
    }

    /// Where x, y and z sit in a point, checked against the point, the rows and the data.
    pub fn layout(&self) -> Result<Layout, LayoutError> {
        let names = || {
            let list: Vec<&str> = self.fields.iter().map(|f| f.name.as_str()).collect();
            list.join(", ")
        };
        let axis = |axis: &'static str| -> Result<(usize, Scalar), LayoutError> {
            let field = self.fields.iter().find(|f| f.name == axis).ok_or_else(|| {
                LayoutError::MissingAxis {
                    axis,
                    fields: names(),
                }
            })?;
            let scalar = datatype(field.datatype).ok_or(LayoutError::Datatype {
                axis,
                datatype: field.datatype,
            })?;
            let end = u64::from(field.offset) + scalar.size() as u64;
            if end > u64::from(self.point_step) {
                return Err(LayoutError::PastPoint {
                    axis,
                    offset: field.offset,
                    size: scalar.size(),
                    point_step: self.point_step,
                });
            }
            Ok((field.offset as usize, scalar))
        };
        let (x, y, z) = (axis("x")?, axis("y")?, axis("z")?);
        let row = u64::from(self.width) * u64::from(self.point_step);
        if self.height > 1 && u64::from(self.row_step) < row {
            return Err(LayoutError::RowStep {
                row_step: self.row_step,
                width: self.width,
                point_step: self.point_step,
            });
        }
        let need = if self.slots() == 0 {
            0
        } else {
            u64::from(self.height - 1) * u64::from(self.row_step) + row
        };
        if need > self.data.len() as u64 {
            return Err(LayoutError::ShortData {
                height: self.height,
                width: self.width,
                point_step: self.point_step,
                row_step: self.row_step,
                need,
                have: self.data.len(),
            });
        }
        Ok(Layout {
            axes: [x, y, z],
            endian: if self.is_bigendian {
                Endian::Big
            } else {
                Endian::Little
            },
        })
    }

    /// Each point's x, y, z as f64, in row order, non-finite ones included (the caller counts
    /// them). `layout` must be this message's; the reads stay inside `data` whatever it is.
    pub fn points(&self, layout: Layout) -> impl Iterator<Item = [f64; 3]> + '_ {
        let (step, row_step) = (self.point_step as usize, self.row_step as usize);
        // Rows of no points are not walked: 2^32 of them would be a loop of nothing.
        let rows = if self.width == 0 { 0 } else { self.height };
        (0..rows as usize).flat_map(move |r| {
            (0..self.width as usize).map(move |c| {
                let start = r.saturating_mul(row_step).saturating_add(c * step);
                let point = self.data.get(start..).unwrap_or(&[]);
                layout.axes.map(|(offset, scalar)| {
                    point
                        .get(offset..)
                        .and_then(|b| scalar.read(b, layout.endian))
                        .unwrap_or(f64::NAN)
                })
            })
        })
    }
}

/// The offsets and types of a message's x, y, z ([`PointCloud2::layout`]).
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    axes: [(usize, Scalar); 3],
    endian: Endian,
}

/// `PointField`'s datatype constants.
fn datatype(d: u8) -> Option<Scalar> {
    Some(match d {
        1 => Scalar::I8,
        2 => Scalar::U8,
        3 => Scalar::I16,
        4 => Scalar::U16,
        5 => Scalar::I32,
        6 => Scalar::U32,
        7 => Scalar::F32,
        8 => Scalar::F64,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A little-endian CDR PointCloud2 of `points` as FLOAT32 x, y, z after a 4-byte field.
    fn message(points: &[[f32; 3]], big: bool) -> Vec<u8> {
        let mut m = vec![0, 1, 0, 0];
        let pad = |m: &mut Vec<u8>, n: usize| {
            while !(m.len() - 4).is_multiple_of(n) {
                m.push(0);
            }
        };
        let u32 = |m: &mut Vec<u8>, v: u32| {
            pad(m, 4);
            m.extend_from_slice(&v.to_le_bytes());
        };
        let string = |m: &mut Vec<u8>, s: &str| {
            u32(m, s.len() as u32 + 1);
            m.extend_from_slice(s.as_bytes());
            m.push(0);
        };
        u32(&mut m, 7); // sec
        u32(&mut m, 0); // nanosec
        string(&mut m, "lidar");
        u32(&mut m, 1);
        u32(&mut m, points.len() as u32);
        u32(&mut m, 4);
        for (name, offset) in [("ring", 0), ("z", 12), ("x", 4), ("y", 8)] {
            string(&mut m, name);
            u32(&mut m, offset);
            m.push(if name == "ring" { 4 } else { 7 });
            u32(&mut m, 1);
        }
        m.push(u8::from(big));
        u32(&mut m, 16);
        u32(&mut m, 16 * points.len() as u32);
        u32(&mut m, 16 * points.len() as u32);
        for p in points {
            m.extend_from_slice(&[9, 9, 9, 9]);
            for v in [p[0], p[1], p[2]] {
                m.extend_from_slice(&if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                });
            }
        }
        m.push(1);
        m
    }

    #[test]
    fn any_order_and_either_byte_order() {
        let points = [[1.0, 2.0, 3.0], [-4.5, f32::NAN, 6.0]];
        for big in [false, true] {
            let bytes = message(&points, big);
            let cloud = PointCloud2::parse(&bytes).unwrap();
            assert_eq!(cloud.header.frame_id, "lidar");
            let got: Vec<[f64; 3]> = cloud.points(cloud.layout().unwrap()).collect();
            assert_eq!(got[0], [1.0, 2.0, 3.0]);
            assert_eq!(got[1][0], -4.5);
            assert!(got[1][1].is_nan());
        }
    }

    #[test]
    fn a_layout_past_the_data_is_refused() {
        let bytes = message(&[[1.0, 2.0, 3.0]], false);
        let mut cloud = PointCloud2::parse(&bytes).unwrap();
        cloud.width = 2;
        assert!(matches!(cloud.layout(), Err(LayoutError::ShortData { .. })));
        cloud.width = 1;
        cloud.point_step = 14;
        assert!(matches!(cloud.layout(), Err(LayoutError::PastPoint { .. })));
        cloud.point_step = 16;
        cloud.fields.retain(|f| f.name != "y");
        assert!(matches!(
            cloud.layout(),
            Err(LayoutError::MissingAxis { axis: "y", .. })
        ));
        // 2^32 - 1 empty rows: no points, and no loop over them.
        let mut cloud = PointCloud2::parse(&bytes).unwrap();
        cloud.width = 0;
        cloud.height = u32::MAX;
        assert_eq!(cloud.points(cloud.layout().unwrap()).count(), 0);
        // Every truncation of the message is an error, never a panic.
        for n in 0..bytes.len() {
            assert!(PointCloud2::parse(&bytes[..n]).is_err(), "{n}");
        }
    }
}
