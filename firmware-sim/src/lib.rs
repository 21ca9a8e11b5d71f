//! `mema-firmware-sim`: the mema core run exactly as firmware runs it, and checked.
//!
//! The firmware parts are `no_std` and allocate nothing, so the Cortex-M4F image in `image/`
//! links the very same code:
//! - [`firmware`]: the application state (UART ring, frame decoder, streaming mapper) in one
//!   struct meant for a `static`, advanced by [`firmware::Firmware::tick`], with snapshots for
//!   restarts after a reset;
//! - [`source`]: the byte-source boundary and a UART that delivers a capture in seeded chunks;
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
pub mod firmware;
pub mod source;

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
