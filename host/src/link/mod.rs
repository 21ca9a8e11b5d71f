//! The rangefinder link on the host: frames from a cloud (the scanner side, [`frames`]), bytes
//! into the decoder and the streaming mapper (the robot side, [`stream`]), serial ports and
//! pseudo-terminals ([`port`]) and capture files ([`capture`]), and a mapping device's session
//! ([`session`], [`device`]) or a listener's, the map of a sensor wired to the device
//! ([`listen`]).
//!
//! The loops that run a link until its end (`mema stream`, `record`, `replay`, `scanner-sim`)
//! are the command line's: they own Ctrl-C, progress lines and exit statuses.
pub mod capture;
pub mod carving;
pub mod device;
pub mod frames;
#[cfg(feature = "fuzzing")]
pub mod fuzz_checks;
pub mod lag;
pub mod listen;
pub mod port;
pub mod queries;
pub mod scanner;
pub mod session;
pub mod stream;
