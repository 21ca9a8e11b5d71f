//! What the stream counts as it maps, for a caller to report.

/// Counters a caller reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    pub points: u64,
    pub non_finite: u64,
    pub merges: u64,
    pub refits: u64,
    pub grid_rebuilds: u64,
    /// Tolerance mode: merges forced by the capacity although over the tolerance.
    pub forced_merges: u64,
    /// Clusters frozen into fitted entities.
    pub frozen: u64,
    /// Points that joined their nearest centre beyond the join radius because the pacing's
    /// credit could not pay for room ([`super::pacing`]).
    pub paced_joins: u64,
    /// Points the pacing's credit could not pay room for, with no centre within
    /// [`super::PACED_REACH`] join radii: left out of the clusters ([`super::pacing`]).
    pub paced_shed: u64,
    /// Pairs of frozen entities merged to make room for another ([`super::coarsen`]).
    pub coarsened: u64,
    /// Scans of the frozen store for pairs to coarsen, each a device's costliest step.
    pub scans: u64,
    /// Working clusters carved: seen through by later scans ([`super::carve`]).
    pub carved: u64,
    /// Working clusters the finish merged, finer than a coarsened store ([`super::StreamMapper::finish`]).
    pub balanced: u64,
    /// Frozen shells taken back into working memory by a point near them ([`super::thaw`]).
    pub thawed: u64,
}
