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
    /// the finest grid that holds them all.
    pub fn layout(&self) -> Layout {
        match self.params.model {
            StreamModel::Paper => Layout::AxisAligned,
            StreamModel::Shells(_) => {
                Layout::Quantized(Quantization::for_entities(self.entities()))
            }
        }
    }

    /// The entities as a file in `layout` stores them: on its grid when quantized, as they are
    /// otherwise.
    pub fn stored_entities(&self, layout: Layout) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        self.entities().map(move |e| match layout {
            Layout::Quantized(grid) => grid.quantize(e),
            _ => e,
        })
    }

    /// Bytes of the map's `.mema` file as it stands.
    pub fn encoded_len(&self) -> usize {
        self.layout().encoded_len(self.entities().count())
    }

    /// The map's `.mema` bytes (in [`StreamMapper::layout`]) into `out`, returning their length.
    pub fn encode_into(&self, origin: [f64; 3], out: &mut [u8]) -> Result<usize, EncodeError> {
        let layout = self.layout();
        encode_as(layout, origin, self.stored_entities(layout), out)
    }

    /// The map's `.mema` bytes handed to `sink` piece by piece: a device needs no buffer for
    /// the whole map.
    pub fn encode_pieces(
        &self,
        origin: [f64; 3],
        sink: impl FnMut(&[u8]),
    ) -> Result<usize, EncodeError> {
        let layout = self.layout();
        encode_pieces_as(layout, origin, self.stored_entities(layout), sink)
    }
}
