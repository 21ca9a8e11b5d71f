//! `mema-firmware-sim`: the device's code (`mema-firmware`, the crate the Cortex-M4F image in
//! `image/` and the STM32F405 board link) run exactly as firmware runs it, and checked:
//! - [`fault`]: a seeded fault injector that wraps any byte source (noise, overruns, truncated
//!   frames, resets);
//! - [`board`]: a board model stricter than the hardware: a RAM budget checked before anything
//!   runs, peak use tracked, a second owner of the state refused.
//!
//! With the `std` feature: [`harness`] drives source, board and firmware and logs what was
//! accepted, and [`fuzz_checks`] holds the carrier's fuzz property and the link's seeds. With `reference`: an independent f64 reference on `nalgebra` ([`mod@reference`]) and
//! its comparison with the core ([`compare`]), and the memory budget report ([`budget`]).
#![cfg_attr(not(feature = "std"), no_std)]
#![deny(missing_debug_implementations)]

pub mod board;
pub mod fault;

#[cfg(feature = "reference")]
pub mod budget;
#[cfg(feature = "reference")]
pub mod compare;
#[cfg(feature = "std")]
pub mod fuzz_checks;
#[cfg(feature = "std")]
pub mod harness;
#[cfg(feature = "std")]
pub mod pacing;
#[cfg(feature = "reference")]
pub mod reference;
