//! The streaming mapper's shells and its map file.
//!
//! A shell is a function of the cluster's mean and covariance, which the moments hold exactly at
//! every point, so a working cluster's shell is computed when the map is read: no refit
//! schedule, no stored fit, and a snapshot is always current. A frozen cluster keeps its shell
//! as a [`super::FrozenEntity`], and so does a working one once the stream is finished.
//!
//! Shells are written quantized (14 bytes an entity, as `mema map` writes them), and the mapper
//! hands out its entities already on that grid, so a host's map in memory, its file read back
//! and a device's bytes sent piece by piece are one and the same.

use super::{FrozenEntity, StreamCluster, StreamMapper, StreamModel};
use crate::geometry::Entity;
use crate::map::record::Quantization;
use crate::map::{EncodeError, Layout, MapEntity, encode_as, encode_pieces_counted};
use crate::moments::FixedMoments;
use crate::shell::{ShellParams, shell_single};

/// The shell of a cluster's moments; `None` for an empty cluster or a non-finite covariance.
pub fn shell_of(moments: &FixedMoments, params: &ShellParams) -> Option<Entity> {
    let (mean, covariance) = moments.covariance()?;
    shell_single(mean, covariance, params)
}

/// A working cluster's shell as [`StreamMapper::finish`] kept it: `entity` and the rotation code
/// in `stale`, which shells never use for refits.
pub(super) fn kept_shell(c: &StreamCluster) -> FrozenEntity {
    FrozenEntity {
        entity: c.entity,
        rotation: c.stale,
    }
}

/// A quantized file's centre step that is fine whatever the shells' thickness: the grid moves a
/// centre by at most half a step, 0.125 mm, under a depth camera's noise (a millimetre and more)
/// and a quarter of the rounding of a stream sent in millimetres. A shell thinner than a few such
/// steps is a cloud on a coarser lattice than the grid (a depth frame's points sent in 1 mm
/// units lie on depth layers), not a surface the grid could move off.
pub const QUANTIZED_STEP_ALWAYS: f32 = 2.5e-4;

/// Centre steps a shell must be thick for the grid not to move it off its surface by more than
/// an eighth of its thickness.
pub const THIN_STEPS: f32 = 4.0;

/// Whether a streamed map of `all` shells, `thin` of them thinner than [`THIN_STEPS`] centre
/// steps of `step` (its half extent over 32,767), is written on the quantized grid: when the
/// step is below any sensor's noise or a quarter of `resolution` (the unit the points were
/// rounded to on their wire, 0 if unknown), or at most half of the shells are that thin. Why
/// the resolution: a shell thinner than the points' own rounding is a few points on its
/// lattice, not a surface, and the grid moves it by an eighth of that rounding at most (an
/// airborne scan 4.6 km across, sent in 10 m units for its 63 m spacing, had 110 of 148 shells
/// "thinner" than 4 steps of 7 cm, and its map took 41 bytes an entity).
pub fn quantizes(step: f32, thin: usize, all: usize, resolution: f32) -> bool {
    step <= QUANTIZED_STEP_ALWAYS.max(0.25 * resolution) || 2 * thin <= all
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Notes that the points that follow were rounded to `unit` metres on their wire (a
    /// frame's unit): the map keeps the finest seen ([`quantizes`]).
    pub fn note_resolution(&mut self, unit: f32) {
        if unit > 0.0 && unit.is_finite() && (self.resolution == 0.0 || unit < self.resolution) {
            self.resolution = unit;
        }
    }

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
            StreamModel::Shells(_) if self.final_shells => kept_shell(c).to_entity(),
            StreamModel::Shells(p) => shell_of(&c.moments, &p).unwrap_or(Entity::from(c.entity)),
        }
    }

    /// Makes each working cluster's shell once, at the end of the stream, and keeps it in the
    /// cluster as a frozen entity is kept (the rotation to its code's quarter degree, which is
    /// all a quantized file stores). Why: writing a map reads every shell twice (the layout,
    /// then the records), and with its eigen-solve in software f64 a shell cost a device about
    /// 100,000 instructions: making 150 of them a second time was an eighth of the 64 KiB
    /// image's whole run on car6 (in f32, [`crate::shell::symmetric_eigen_single`], still a
    /// fraction of it).
    pub(super) fn keep_final_shells(&mut self) {
        let StreamModel::Shells(params) = self.params.model else {
            return;
        };
        for i in 0..self.clusters.len() {
            self.keep_shell(i, &params);
        }
        self.final_shells = true;
    }

    /// Working cluster `i`'s shell made from its moments and kept (the sphere it opened with,
    /// unturned, if its sums overflowed).
    pub(super) fn keep_shell(&mut self, i: usize, params: &ShellParams) {
        if let Some(c) = self.clusters.get_mut(i) {
            let kept = shell_of(&c.moments, params).map_or(
                FrozenEntity {
                    entity: c.entity,
                    rotation: 0,
                },
                |s| FrozenEntity::of(&s),
            );
            c.entity = kept.entity;
            c.stale = kept.rotation;
        }
    }

    /// How the map is written: the paper's axis-aligned fits in version 1; shells quantized
    /// around the centre of their box, on the finest grid that holds them all, unless that
    /// grid's centre step passes 0.1 mm and more than half of the shells are thinner than
    /// [`THIN_STEPS`] steps ([`quantizes`]): a map kilometres across, or one far entity, would
    /// then move most shells off their surfaces, and the shells are written in f32 instead
    /// (version 2, 41 bytes an entity; version 1 if none is turned).
    pub fn layout(&self) -> Layout {
        match self.params.model {
            StreamModel::Paper => Layout::AxisAligned,
            StreamModel::Shells(_) => {
                let shift = self.box_centre();
                // One pass: what the grid needs (the farthest centre, the shortest and longest
                // finite semi-axes, as `Quantization::for_entities` takes them), whether any
                // shell is turned, and the shells' shortest semi-axes by power of two (their
                // weights' exponents), to count those thinner than four centre steps without
                // sorting them.
                let (mut far, mut turned, mut all) = (0.0f32, false, 0usize);
                let (mut shortest, mut longest) = (f64::INFINITY, 0.0f64);
                let mut by_exponent = [0u32; 256];
                for e in self.shifted(shift) {
                    for v in e.entity.center.to_array() {
                        if v.is_finite() {
                            far = far.max(v.abs());
                        }
                    }
                    for r in e.entity.semi_axes_f64() {
                        if r.is_finite() && r > 0.0 {
                            shortest = shortest.min(r);
                            longest = longest.max(r);
                        }
                    }
                    turned |= !e.entity.rotation.is_identity();
                    let [a, b, c] = e.entity.weights;
                    // The shortest semi-axis has the largest weight, 1/r^2.
                    let exponent = (a.max(b).max(c).to_bits() >> 23) & 0xff;
                    if let Some(n) = by_exponent.get_mut(exponent as usize) {
                        *n += 1;
                    }
                    all += 1;
                }
                let grid = Quantization::for_extent(f64::from(far), shortest, longest);
                // Shells thinner than four steps (within a factor of 2, by whole exponents):
                // the grid would move them off their surfaces by an eighth of their thickness.
                let step = far / 32_767.0;
                let limit = (THIN_STEPS * step).max(f32::MIN_POSITIVE);
                let thin_from = ((1.0 / (limit * limit)).to_bits() >> 23) & 0xff;
                let thin: u32 = by_exponent.iter().skip(thin_from as usize).sum();
                if quantizes(step, thin as usize, all, self.resolution) {
                    Layout::Quantized(grid)
                } else if turned {
                    Layout::Oriented
                } else {
                    // As a host map with these entities is written.
                    Layout::AxisAligned
                }
            }
        }
    }

    /// The centre of the box around the clusters' centres and the frozen entities': near the
    /// centre of the entities' box (a shell's centre is its cluster's mean), without making a
    /// shell. Any shift near the middle serves: the grid is fitted to the shifted entities.
    fn box_centre(&self) -> [f32; 3] {
        let frozen = self.frozen.iter().map(|f| f.entity.center);
        let (lo, hi) =
            crate::geometry::finite_box(frozen.chain(self.clusters.iter().map(|c| c.center)));
        // Halves first: the sum of two large centres cannot overflow.
        core::array::from_fn(|j| {
            let (l, h) = (lo[j], hi[j]);
            if l <= h { l / 2.0 + h / 2.0 } else { 0.0 }
        })
    }

    /// Where a file in `layout` puts its origin, in the mapper's frame: a quantized file at the
    /// centre of its entities' box, so its centre step is the map's own half extent over
    /// 32,767 wherever the receiver's origin lies (around that origin, a small scene at its far
    /// side got a step of its distance over 32,767: 15 mm at 500 m); f32 records at the
    /// receiver's origin, where a shift could only round them.
    pub fn file_shift(&self, layout: Layout) -> [f32; 3] {
        match layout {
            Layout::Quantized(_) => self.box_centre(),
            _ => [0.0; 3],
        }
    }

    /// The origin of a file in `layout` for a mapper whose points are relative to `origin` (the
    /// receiver's).
    pub fn file_origin(&self, origin: [f64; 3], layout: Layout) -> [f64; 3] {
        let shift = self.file_shift(layout);
        core::array::from_fn(|j| origin[j] + f64::from(shift[j]))
    }

    /// The entities moved by `-shift`.
    fn shifted(&self, shift: [f32; 3]) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        let [sx, sy, sz] = shift;
        self.entities().map(move |mut e| {
            let c = e.entity.center;
            e.entity.center = crate::geometry::Point3::new(c.x - sx, c.y - sy, c.z - sz);
            e
        })
    }

    /// The entities as a file in `layout` stores them, around the file's origin: on its grid
    /// when quantized, as they are otherwise.
    pub fn stored_entities(&self, layout: Layout) -> impl Iterator<Item = MapEntity> + Clone + '_ {
        self.shifted(self.file_shift(layout))
            .map(move |e| match layout {
                Layout::Quantized(grid) => grid.quantize(e),
                _ => e,
            })
    }

    /// Bytes of the map's `.mema` file as it stands.
    pub fn encoded_len(&self) -> usize {
        self.layout().encoded_len(self.entity_count())
    }

    /// Entities in the map, frozen and working: what [`StreamMapper::entities`] yields, without
    /// making a shell.
    pub fn entity_count(&self) -> usize {
        self.frozen.len() + self.clusters.len()
    }

    /// The map's `.mema` bytes (in [`StreamMapper::layout`]) into `out`, returning their length;
    /// `origin` is the receiver's.
    pub fn encode_into(&self, origin: [f64; 3], out: &mut [u8]) -> Result<usize, EncodeError> {
        let layout = self.layout();
        encode_as(
            layout,
            self.file_origin(origin, layout),
            self.shifted(self.file_shift(layout)),
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
        self.encode_pieces_in(self.layout(), origin, sink)
    }

    /// [`StreamMapper::encode_pieces`] in `layout`, which must be [`StreamMapper::layout`]: for
    /// a caller that has it already (each is a pass over the shells).
    pub fn encode_pieces_in(
        &self,
        layout: Layout,
        origin: [f64; 3],
        sink: impl FnMut(&[u8]),
    ) -> Result<usize, EncodeError> {
        encode_pieces_counted(
            layout,
            self.file_origin(origin, layout),
            self.entity_count(),
            self.shifted(self.file_shift(layout)),
            core::iter::empty(),
            sink,
        )
    }
}
