//! What happens to the clusters as points arrive, for a caller that follows which points each
//! cluster holds: the mapper keeps only moments, so without this nobody outside could rebuild a
//! cluster from its points (the tests do, to check each entity against a direct computation).

/// Told of every change to the working clusters, in order. Every method defaults to nothing,
/// and `()` observes nothing: [`super::StreamMapper::add`] is `add_observed(p, &mut ())`.
pub trait Observer {
    /// The point joined working cluster `index`.
    fn joined(&mut self, _index: usize) {}
    /// The point opened a new working cluster at `index`, the end of the working set.
    fn opened(&mut self, _index: usize) {}
    /// The point joined no cluster: the pacing shed it ([`super::PACED_REACH`]).
    fn shed(&mut self) {}
    /// Cluster `from`'s points joined cluster `into`; `from` is [`Observer::removed`] later.
    fn merged(&mut self, _into: usize, _from: usize) {}
    /// Cluster `index` became the last frozen entity; it is [`Observer::removed`] next.
    fn frozen(&mut self, _index: usize) {}
    /// Cluster `index` left the working set by swap-remove: the last cluster took its slot.
    fn removed(&mut self, _index: usize) {}
    /// Frozen entity `from` merged into frozen entity `into` (a coarsening,
    /// [`super::coarsen`]), and the last frozen entity took `from`'s slot by swap-remove.
    fn coarsened(&mut self, _into: usize, _from: usize) {}
    /// Frozen entity `from` came back as working cluster `index`, the end of the working set,
    /// holding `patch` ([`super::thaw::patch_points`]) in place of its points; the last frozen
    /// entity took `from`'s slot by swap-remove. The point that thawed it is
    /// [`Observer::joined`] to it next.
    fn thawed(&mut self, _from: usize, _index: usize, _patch: &[crate::Point3]) {}
}

impl Observer for () {}
