//! Carving frozen entities: a device's layout freezes a cluster once the scan has left it, and
//! a person who walked on may freeze before two scans have seen through where they stood. A
//! frozen entity keeps no moments, so it is judged by its shape: its centre, and the ends of
//! its two longest axes (three quarters of each, as a working cluster's 1.5 deviations are of
//! a shell's two) moved to its far side along the ray (its support in the ray's direction), as
//! [`Carver::sees_through`] judges a cluster, except that one of the four ends may look seen
//! (`SHORT_ENDS`). A scan that saw through it counts; one whose
//! nearest return lies at or before its centre (its surface, or something in front) starts the
//! count again; one with no return near it, or with two axis ends it did not see through,
//! leaves the count as it is. [`SEEN_THROUGH`]
//! counts and it leaves the map, the last frozen entity taking its slot: the slot is marked
//! changed, so a downlink that sent the slot sends it again
//! ([`StreamMapper::take_changed`]).

use super::{Carver, SEEN_THROUGH, Sight};
use crate::geometry::Point3;
use crate::num::square_root;
use crate::stream::{FrozenEntity, StreamMapper};

/// Axis ends tested, as a fraction of the semi-axis.
const AXIS_REACH: f32 = 0.75;

/// Axis ends that may look seen while the entity is still seen through: one. A piece of
/// someone standing on the floor has its lowest end at the floor, and at a device's pixels
/// (1.45 degrees a row on the board) the row below that end meets the floor nearer than the end
/// does; asking all four ends kept two to three such pieces of the walking drive's walker in the
/// board's map, 9.0 % of the walker's points (5.3 % with one end let go; `tests/walker.rs`).
/// An entity across an inside corner has its ends on the walls (three of the four in
/// `a_frozen_entity_across_a_corner_stays`), and stays.
const SHORT_ENDS: usize = 1;

/// What a scan saw of a frozen entity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Through,
    Seen,
    Unknown,
}

impl<const N: usize> Carver<N> {
    /// Judges frozen entity `index` by the scan that ended, and removes it at its
    /// [`SEEN_THROUGH`]th count.
    pub(super) fn judge_frozen<const K: usize, const G: usize, const F: usize>(
        &self,
        index: usize,
        mapper: &mut StreamMapper<K, G, F>,
    ) {
        let Some(entity) = mapper.frozen().get(index) else {
            return;
        };
        let verdict = self.verdict(entity);
        let count = mapper.seen_through_count(index);
        let count = match verdict {
            Verdict::Through => count.saturating_add(1),
            Verdict::Seen => 0,
            Verdict::Unknown => count,
        };
        if count < SEEN_THROUGH {
            mapper.set_seen_through_count(index, count);
            return;
        }
        mapper.remove_frozen(index);
    }

    fn verdict(&self, e: &FrozenEntity) -> Verdict {
        let w = e.entity.weights;
        if !w.iter().all(|&w| w > 0.0 && w.is_finite()) {
            // A pseudocylinder or a pair of planes reaches without end: never judged.
            return Verdict::Unknown;
        }
        let o = self.image.geometry().origin;
        let c = e.entity.center;
        let d = [c.x - o.x, c.y - o.y, c.z - o.z];
        let r = square_root(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if !(r > 0.0 && r.is_finite()) {
            return Verdict::Unknown;
        }
        // The centre first, as it is: most entities a scan did not see through fail here,
        // before their rotation (costly on a device) is decoded.
        match self.sight(c) {
            Sight::Through => {}
            Sight::Short => return Verdict::Seen,
            Sight::Nothing => return Verdict::Unknown,
        }
        let semi_axes = w.map(|w| 1.0 / square_root(w));
        let rotation = e.to_entity().rotation;
        let u = d.map(|v| f64::from(v / r));
        // How far the entity reaches along the ray: its support in the ray's direction.
        let local = rotation.inverse_rotate(u);
        let reach = libm::sqrt(
            (0..3)
                .map(|j| {
                    let a = f64::from(semi_axes.get(j).copied().unwrap_or(0.0));
                    let l = local.get(j).copied().unwrap_or(0.0);
                    a * a * l * l
                })
                .sum::<f64>(),
        );
        let far = |offset: [f64; 3]| {
            let p = [0, 1, 2].map(|j| {
                f64::from(c.to_array().get(j).copied().unwrap_or(0.0))
                    + offset.get(j).copied().unwrap_or(0.0)
                    + reach * u.get(j).copied().unwrap_or(0.0)
            });
            Point3::new(p[0] as f32, p[1] as f32, p[2] as f32)
        };
        // The ends of the two longest axes (the rotation's columns in the world), moved to the
        // far side: an entity across an inside corner has its centre in free space, but its
        // ends on the walls. (The far side of the centre itself is not asked: a walker's leg,
        // frozen, stands where its later steps and the floor crowd the pixels around it, and
        // asking it kept half the walker in the board's map.)
        let mut order = [0, 1, 2];
        order.sort_unstable_by(|&a, &b| semi_axes[b].total_cmp(&semi_axes[a]));
        let mut short = 0;
        for &j in order.iter().take(2) {
            let mut unit = [0.0; 3];
            if let Some(v) = unit.get_mut(j) {
                *v = 1.0;
            }
            let axis = rotation.rotate(unit);
            let length = f64::from(AXIS_REACH * semi_axes.get(j).copied().unwrap_or(0.0));
            for sign in [1.0, -1.0] {
                if self.sight(far(axis.map(|v| sign * length * v))) == Sight::Short {
                    short += 1;
                    if short > SHORT_ENDS {
                        return Verdict::Unknown;
                    }
                }
            }
        }
        Verdict::Through
    }
}
