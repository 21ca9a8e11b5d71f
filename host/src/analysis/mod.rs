//! Judging maps: eq. 13, the two-way fidelity score and the paper's tables.
pub mod eval;
pub mod fidelity;
pub mod stats;
