//! `mema-core`: the Multiellipsoidal Mapping Algorithm without `std`, an allocator, or panics.
//!
//! Pipeline (paper, Section 3): [`kmeans`] clusters the points (k-means++ seeding, Lloyd
//! iterations); each cluster's [`moments`] give eq. 12's [`fitness`] in O(1); [`de`] fits the
//! semi-axes ([`fit`]); [`geometry`] stores each entity as centre + `w_j = 1/r_j^2` with
//! degenerated axes as `w_j = 0`; [`closest_point`] gives eq. 13's surface error; [`map`] holds
//! the entities in fixed capacity and encodes the `.mema` file.
//!
//! Contract: every function takes caller-provided slices or fixed-size types; capacity and bad
//! input come back as typed errors; the same input and seed give the same bits on every target
//! (IEEE-754 f32/f64 arithmetic plus `libm`, no fused or platform math).
#![no_std]
#![deny(missing_debug_implementations, unsafe_code)]
// `!(x > 0.0)` is deliberate throughout: it is true for NaN, which must take the safe branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops mirror the subscripts of the equations they implement (j, k over axes).
#![allow(clippy::needless_range_loop)]

pub mod closest_point;
pub mod de;
pub mod de32;
pub mod fit;
pub mod fit32;
pub mod fitness;
pub mod free_space;
#[cfg(feature = "fuzzing")]
pub mod fuzz_checks;
pub mod geometry;
pub mod grid;
pub mod kmeans;
pub mod link;
pub mod map;
pub mod moments;
mod num;
pub mod query;
pub mod rng;
pub mod rotation;
pub mod shell;
pub mod stream;
pub mod transform;

pub use geometry::{Degeneration, Entity, EntityKind, Point3};
pub use map::{Map, MapEntity};
pub use rotation::Rotation;

/// Test helpers: tests return `Result` and use `?`, so core has no `expect` even in tests.
#[cfg(test)]
mod test_support {
    pub type TestResult = Result<(), &'static str>;

    pub trait OrFail<T> {
        fn or_fail(self, what: &'static str) -> Result<T, &'static str>;
    }

    impl<T> OrFail<T> for Option<T> {
        fn or_fail(self, what: &'static str) -> Result<T, &'static str> {
            self.ok_or(what)
        }
    }

    impl<T, E> OrFail<T> for Result<T, E> {
        fn or_fail(self, what: &'static str) -> Result<T, &'static str> {
            self.map_err(|_| what)
        }
    }

    /// Every flip of a bit pattern in any byte of a frame's COBS block, and every cut of it,
    /// makes `decodes` refuse it (a flip to the delimiter is a cut, made by the line).
    pub fn damaged_blocks_are_refused<const N: usize>(
        block: [u8; N],
        len: usize,
        decodes: impl Fn(&mut [u8]) -> bool,
    ) -> TestResult {
        for i in 0..len {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut damaged = block;
                let b = damaged.get_mut(i).or_fail("byte")?;
                *b ^= flip;
                if *b != 0 && decodes(damaged.get_mut(..len).or_fail("block")?) {
                    return Err("a flipped byte was decoded");
                }
            }
        }
        for cut in 0..len {
            let mut damaged = block;
            if decodes(damaged.get_mut(..cut).or_fail("cut")?) {
                return Err("a cut block was decoded");
            }
        }
        Ok(())
    }

    /// The bytes of a hex string (PROTOCOL.md's examples) into `out`; the count.
    pub fn hex(s: &str, out: &mut [u8]) -> Result<usize, &'static str> {
        let mut n = 0;
        for pair in s.split_whitespace() {
            *out.get_mut(n).or_fail("room")? = u8::from_str_radix(pair, 16).or_fail("hex")?;
            n += 1;
        }
        Ok(n)
    }
}
