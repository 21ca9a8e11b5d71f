//! The streaming mapper's shells and its map file.
//!
//! A shell is a function of the cluster's mean and covariance, which the moments hold exactly at
//! every point, so a working cluster's shell is computed when the map is read: no refit
//! schedule, no stored fit, and a snapshot is always current. A frozen cluster keeps its shell
//! as a [`super::FrozenEntity`].
//!
//! Shells are written quantized (14 bytes an entity, as `mema map` writes them), and the mapper
//! hands out its entities already on that grid, so a host's map in memory, its file read back
//! and a device's bytes sent piece by piece are one and the same.

use super::{StreamCluster, StreamMapper, StreamModel};
use crate::geometry::Entity;
use crate::map::record::Quantization;
use crate::map::{EncodeError, Layout, MapEntity, encode_as, encode_pieces_as};
use crate::moments::FixedMoments;
use crate::shell::{ShellParams, shell};

/// The shell of a cluster's moments; `None` for an empty cluster or a non-finite covariance.
pub fn shell_of(moments: &FixedMoments, params: &ShellParams) -> Option<Entity> {
    let (mean, covariance) = moments.covariance()?;
    shell(mean, covariance, params)
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    pub(super) fn is_shells(&self) -> bool {
        matches!(self.params.model, StreamModel::Shells(_))
    }

    pub(super) fn sphere_tolerance(&self) -> f64 {
        match self.params.model {
            StreamModel::Paper => self.params.fit.degeneration.sphere_tolerance,
            StreamModel::Shells(p) => p.degeneration.sphere_tolerance,
        }
    }

    /// A working cluster's entity: the paper's latest fit, or the shell of its moments now.
    pub(super) fn working_entity(&self, c: &StreamCluster) -> Entity {
        match self.params.model {
            StreamModel::Paper => Entity::from(c.entity),
            // Points are finite, so only an overflowing sum leaves the opening sphere in place.
            StreamModel::Shells(p) => shell_of(&c.moments, &p).unwrap_or(Entity::from(c.entity)),
        }
    }

    /// How the map is written: the paper's axis-aligned fits in version 1, shells quantized on
    /// the finest grid that holds them all around the file's origin ([`StreamMapper::file_shift`]).
    pub fn layout(&self) -> Layout {
        match self.params.model {
            StreamModel::Paper => Layout::AxisAligned,
            StreamModel::Shells(_) => {
                Layout::Quantized(Quantization::for_entities(self.file_entities()))
            }
        }
    }

    /// Where a quantized file's origin lies in the mapper's frame: the centre of the box around
    /// the entities' centres. The grid's centre step is then the map's own half extent over
    /// 32,767, wherever the receiver's origin lies; around that origin, a small scene at the
    /// far side of it got a step of its distance over 32,767 (15 mm at 500 m). Zero for the
    /// paper's f32 records, which a shift could only round.
    pub fn file_shift(&self) -> [f32; 3] {
        if !self.is_shells() {
            return [0.0; 3];
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for e in self.entities() {
            for ((l, h), v) in lo
                .iter_mut()
                .zip(hi.iter_mut())
                .zip(e.entity.center.to_array())
            {
                if v.is_finite() {
                    *l = l.min(v);
                    *h = h.max(v);
                }
            }
        }
        // Halves first: the sum of two large centres cannot overflow.
        core::array::from_fn(|j| {
            let (l, h) = (lo[j], hi[j]);
            if l <= h { l / 2.0 + h / 2.0 } else { 0.0 }
        })
    }

    /// The file's origin for a mapper whose points are relative to `origin` (the receiver's).
    pub fn file_origin(&self, origin: [f64; 3]) -> [f64; 3] {
        let shift = self.file_shift();
        core::array::from_fn(|j| origin[j] + f64::from(shift[j]))
    }

    /// The entities around the file's origin.
    fn file_entities(&self) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        let [sx, sy, sz] = self.file_shift();
        self.entities().map(move |mut e| {
            let c = e.entity.center;
            e.entity.center = crate::geometry::Point3::new(c.x - sx, c.y - sy, c.z - sz);
            e
        })
    }

    /// The entities as a file in `layout` stores them, around the file's origin: on its grid
    /// when quantized, as they are otherwise.
    pub fn stored_entities(&self, layout: Layout) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        self.file_entities().map(move |e| match layout {
            Layout::Quantized(grid) => grid.quantize(e),
            _ => e,
        })
    }

    /// Bytes of the map's `.mema` file as it stands.
    pub fn encoded_len(&self) -> usize {
        self.layout().encoded_len(self.entities().count())
    }

    /// The map's `.mema` bytes (in [`StreamMapper::layout`]) into `out`, returning their length;
    /// `origin` is the receiver's.
    pub fn encode_into(&self, origin: [f64; 3], out: &mut [u8]) -> Result<usize, EncodeError> {
        let layout = self.layout();
        encode_as(
            layout,
            self.file_origin(origin),
            self.stored_entities(layout),
            out,
        )
    }

    /// The map's `.mema` bytes handed to `sink` piece by piece: a device needs no buffer for
    /// the whole map.
    pub fn encode_pieces(
        &self,
        origin: [f64; 3],
        sink: impl FnMut(&[u8]),
    ) -> Result<usize, EncodeError> {
        let layout = self.layout();
        encode_pieces_as(
            layout,
            self.file_origin(origin),
            self.stored_entities(layout),
            sink,
        )
    }
}
