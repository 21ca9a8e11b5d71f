//! Pacing: the stream's costly steps paid for in points, so a device that keeps up with the
//! points keeps up with the whole stream.
//!
//! Making room for a point far from every centre costs a freeze (one DE fit) or a merge pass,
//! each the price of tens of points that join a cluster (docs/results.md's pacing table has
//! the firmware's measured prices). Entering new ground, a scanner can ask for room at
//! every point: a DE fit per point outruns a 921,600-baud link whatever the processor's
//! average, and the receive ring overflows (issue 13). So each ingested point earns one credit,
//! a freeze or merge pass spends its price in credits, and saved credit is capped: over any
//! stretch of `n` points the stream runs at most `(n + burst) / price` of them. When the credit
//! is short, the point joins its nearest centre however far it is (a coarser cluster there, as
//! if the join radius had grown), so no point is dropped and the cost of a point is bounded.
//!
//! Credit is counted in points, never in time: the same points give the same map on every
//! target, at any speed, and the host's replay of a capture is the device's map.

/// Prices in points of credit, and the most credit that can be saved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pacing {
    /// Credits a freeze spends.
    pub freeze: u32,
    /// Credits a merge pass spends.
    pub merge_pass: u32,
    /// The cap on saved credit: the largest burst of costly steps back to back. At least the
    /// dearer price, or that step never runs (every point short of room then joins).
    pub burst: u32,
}

impl Pacing {
    /// No pacing: every freeze and merge pass runs when room is needed.
    pub const NONE: Self = Self {
        freeze: 0,
        merge_pass: 0,
        burst: 0,
    };

    /// The firmware's (and the host's stream, so a replay is the device's map): prices in
    /// proportion to what each step costs the Cortex-M4F (the prices of the pacing test,
    /// `tests/tests/pacing.rs`, on its four captures), so a point costs on average its own work
    /// and at most a credit's worth of a fit or merge pass (docs/firmware.md, "Longest tick, the
    /// link and pacing"). The burst is five freezes.
    pub const DEVICE: Self = Self {
        freeze: 24,
        merge_pass: 80,
        burst: 120,
    };

    /// The credit after one more point.
    pub(super) fn earn(&self, credit: u32) -> u32 {
        credit.saturating_add(1).min(self.burst)
    }
}
