//! Judging maps: eq. 13 of any map against any cloud, the two-way fidelity score, and the
//! paper's tables.
//!
//! Built on [`crate::io`] and the pipeline's eq. 13 ([`crate::mapping::pipeline`]).
pub mod eval;
pub mod fidelity;
pub mod stats;
