//! Thawing: a point that finds no working centre within the join radius but lands near a frozen
//! shell's centre takes that shell back into working memory, instead of opening a new cluster
//! beside it.
//!
//! Why: a stream that returns to ground it left (a mesh's vertices in no sweep order, scans of
//! one object from several sides) finds the clusters it built there frozen, and every return
//! used to open clusters over the same surface, each frozen in turn: bun_zipper's board map
//! covered its points 1.27 times over (the batch map 1.03), its shells as many points apart and
//! twice as thick, 1.28 times the batch map's Chamfer distance at the same bytes. A thawed shell
//! grows with the returning points and freezes again as one patch (docs/design.md, "Returning
//! to frozen ground").
//!
//! A frozen shell keeps no moments, only its centre and axes: it comes back as six points, at
//! plus and minus `sqrt 3` standard deviations along each of its axes, which have its mean and
//! covariance. It keeps no point count either (four bytes each would not fit the 64 KiB image),
//! so it weighs six points against the points that come back to it: those soon outweigh it, as
//! they should where the surface they sample is the one the shell stood for. Only shells thaw:
//! the paper's frozen fits are axis-aligned semi-axes, which stand for no covariance.

use super::{FrozenEntity, Observer, StreamCluster, StreamMapper, StreamModel, center_of};
use crate::geometry::{AxisEntity, Entity, Point3};
use crate::map::record::rotation_column32;
use crate::moments::FixedMoments;
use crate::num::square_root;
use crate::shell::ShellParams;

/// A frozen centre thaws within this share of the join radius of a point that found no working
/// centre within the radius. Over the board's 21 inputs (K = 700, W = 150): 0.35 took bun_zipper
/// from 1.28 to 1.25 times the batch map's Chamfer distance, 0.5 to 1.23, 0.75 to 1.22, with
/// the other inputs within 0.01 of one another; past one radius a thaw pulls in shells a new
/// cluster would not have reached, and at 2.0 bun_zipper scored 1.36.
pub const THAW_REACH: f32 = 0.5;

/// Points a thawed shell comes back as.
pub const PATCH_POINTS: usize = 6;

/// Six points with `frozen`'s mean and covariance: its centre plus and minus `sqrt 3` standard
/// deviations along each of its axes, the shell's semi-axes over `params`' scales (two tangent,
/// the third, the thinnest, normal). `None` for an axis without a finite, positive weight.
pub fn patch_points(frozen: &FrozenEntity, params: &ShellParams) -> Option<[Point3; PATCH_POINTS]> {
    let scales = [
        params.tangent_scale as f32,
        params.tangent_scale as f32,
        params.normal_scale as f32,
    ];
    let c = frozen.entity.center;
    let mut points = [c; PATCH_POINTS];
    for (j, (&w, &scale)) in frozen.entity.weights.iter().zip(scales.iter()).enumerate() {
        if !(w > 0.0 && w.is_finite()) {
            return None;
        }
        // sqrt(3) sigma, with the shell's semi-axis `scale sigma = 1 / sqrt(w)`.
        let reach = 1.732_050_8 / (square_root(w) * scale);
        let [x, y, z] = rotation_column32(frozen.rotation, j).map(|v| v * reach);
        if let Some([plus, minus]) = points.get_mut(2 * j..2 * j + 2) {
            *plus = Point3::new(c.x + x, c.y + y, c.z + z);
            *minus = Point3::new(c.x - x, c.y - y, c.z - z);
        }
    }
    points.iter().all(|p| p.is_finite()).then_some(points)
}

impl<const K: usize, const G: usize, const F: usize> StreamMapper<K, G, F> {
    /// Thaws the frozen shell whose centre is nearest `p` within [`THAW_REACH`] join radii, if
    /// there is one and a working slot free: it becomes the last working cluster, holding its
    /// [`patch_points`], and `p` is the caller's to join to it. Returns its index.
    pub(super) fn thaw_near(&mut self, p: Point3, observer: &mut impl Observer) -> Option<usize> {
        let StreamModel::Shells(params) = self.params.model else {
            return None;
        };
        if !self.freezes() || self.clusters.len() >= self.limit() {
            return None;
        }
        let reach = THAW_REACH * self.radius;
        if self.frozen.is_empty() || !(reach > 0.0) {
            return None;
        }
        let from = self.nearest_frozen_within(p, reach * reach)?;
        let patch = patch_points(self.frozen.get(from)?, &params)?;
        let mut moments = FixedMoments::second_order();
        for &q in &patch {
            moments.add(q);
        }
        let center = center_of(&moments);
        let cluster = StreamCluster {
            moments,
            center,
            entity: AxisEntity::of_axis_aligned(&Entity::sphere(center, 0.0)),
            stale: u32::MAX,
            last_point: self.stats.points as u32,
            seen_through: 0,
        };
        let index = self.clusters.len();
        self.clusters.push(cluster).ok()?;
        self.take_frozen(from);
        self.grid.insert(index, center);
        self.stats.thawed += 1;
        observer.thawed(from, index, &patch);
        Some(index)
    }

    /// The frozen centre nearest `p` strictly within `sqrt(r2)` (ties: the lowest index). A scan
    /// of the store, run only for a point that would otherwise open a cluster.
    fn nearest_frozen_within(&self, p: Point3, r2: f32) -> Option<usize> {
        let mut best = (usize::MAX, r2);
        for (i, f) in self.frozen.iter().enumerate() {
            let d = p.distance_squared(f.entity.center);
            if d < best.1 {
                best = (i, d);
            }
        }
        (best.0 != usize::MAX).then_some(best.0)
    }
}

#[cfg(test)]
mod tests;
