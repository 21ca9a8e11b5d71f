#![no_std]
pub mod closest_point;
pub mod de;
pub mod fit;
pub mod fitness;
pub mod geometry;
pub mod kmeans;
pub mod moments;
pub mod rng;
