//! Freezing: a cluster the scan has left behind is fitted once and kept as its 28-byte
//! [`FrozenEntity`], and its slot in working memory is reused.
//!
//! Why: a cluster's moments are 24 sums of 64 bits (the agreement with direct sums needs them all;
//! `mema-firmware-sim reference --sum-bits`), so a working cluster costs 288 bytes and 400 of
//! them do not fit a 64 KiB part. A scanner sweeps: once it has moved on, a cluster receives no
//! more points, and merging it later (what a full working set otherwise does) only coarsens the
//! map. Freezing keeps it at the resolution it was built at. The cost is that a frozen cluster
//! keeps no moments: points that later return to its region thaw a frozen shell back into
//! working memory ([`super::thaw`]), from its shape alone, and open new clusters beside the
//! paper's frozen fits, which is why a cluster is frozen only after a long idle spell, and why
//! clouds whose point order is not a sweep map worse this way (README, "Streaming").

use super::{Observer, StreamMapper, StreamModel};
use crate::fit::fit_entity_paper;
use crate::geometry::{AxisEntity, Entity};
use crate::map::record::{rotation_code, rotation_of_code};
use crate::rng::stream_rng;

/// A frozen entity: centre and weights (the paper's 24 bytes) and the rotation as the
/// quantized record's smallest-three code, 0 for the identity of the paper's fits.
///
/// Why the code and not a quaternion: the firmware's 250 frozen entities must fit 64 KiB beside
/// 150 working clusters; four bytes each cost 1,000 bytes, a quaternion 4,000. The code is
/// within a quarter of a degree, and it is exactly what a shells map file stores anyway.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct FrozenEntity {
    pub entity: AxisEntity,
    pub rotation: u32,
}

impl FrozenEntity {
    /// An entity as frozen: its rotation kept to the code's precision.
    pub fn of(e: &Entity) -> Self {
        Self {
            entity: AxisEntity {
                center: e.center,
                weights: e.weights,
            },
            rotation: rotation_code(&e.rotation),
        }
    }

    /// The entity the map holds.
    pub fn to_entity(&self) -> Entity {
        Entity::from(self.entity).with_rotation(rotation_of_code(self.rotation))
    }
}

/// A cluster is idle enough to freeze when no point has joined it for this many turnovers of
/// the working set (`max_clusters` points each): a cluster still under the scanner's sweep gets
/// a share of every turnover, one behind it gets none.
pub const IDLE_TURNOVERS: u64 = 8;

/// Random streams of frozen fits: disjoint from `finish`'s (the working index) and from the
/// periodic refits (index in the high 32 bits), so no two fits share a stream.
const FROZEN_STREAMS: u64 = 1 << 63;

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Points since `cluster` last grew.
    pub(super) fn idle(&self, cluster: &super::StreamCluster) -> u32 {
        (self.stats.points as u32).wrapping_sub(cluster.last_point)
    }

    /// Whether this layout freezes clusters: it has a store, and no refits to wait for.
    pub(super) fn freezes(&self) -> bool {
        self.params.max_frozen.min(F) > 0 && self.params.tolerance <= 0.0
    }

    /// Frees a working slot by freezing the longest-idle cluster, if there is room for another
    /// frozen entity (a full store of shells makes one, [`super::coarsen`]) and that cluster
    /// has been idle for [`IDLE_TURNOVERS`] turnovers. Returns whether a slot was freed;
    /// otherwise `freeze_failed` says whether the freeze could not be made (the caller then
    /// merges) or waits for the next scan of the store.
    pub(super) fn freeze_one(&mut self, observer: &mut impl Observer) -> bool {
        if !self.freezes() {
            return false;
        }
        let mut pick: Option<(usize, u32)> = None;
        for (i, c) in self.clusters.iter().enumerate() {
            let idle = self.idle(c);
            // Ties: the lowest index, so the choice does not depend on anything but the points.
            if pick.is_none_or(|(_, best)| idle > best) {
                pick = Some((i, idle));
            }
        }
        self.freeze_failed = true;
        let Some((i, idle)) = pick else {
            return false;
        };
        if u64::from(idle) < IDLE_TURNOVERS * self.limit() as u64 {
            return false;
        }
        if self.store_full() && !self.coarsen_one(observer) {
            return false;
        }
        let stream = FROZEN_STREAMS | self.frozen.len() as u64;
        let fit = self.clusters.get(i).and_then(|c| match self.params.model {
            StreamModel::Paper => {
                let central = c.moments.central()?;
                Some(fit_entity_paper(
                    &central,
                    &self.params.fit,
                    &mut stream_rng(self.params.seed, stream),
                ))
            }
            StreamModel::Shells(params) => super::shells::shell_of(&c.moments, &params),
        });
        let Some(entity) = fit else {
            return false;
        };
        if i >= self.clusters.len() || self.frozen.push(FrozenEntity::of(&entity)).is_err() {
            return false;
        }
        observer.frozen(i);
        self.remove_working(i, observer);
        self.stats.frozen += 1;
        self.freeze_failed = false;
        true
    }
}
