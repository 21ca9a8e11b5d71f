#![no_std]
pub mod de;
pub mod fit;
pub mod fitness;
pub mod geometry;
pub mod moments;
pub mod rng;
