//! Everything that crosses a serial line, in one framing: a raw frame ends in its CRC-32
//! ([`crc32`]), is COBS-encoded ([`cobs`]) and followed by one `0x00` delimiter. [`framing`]
//! seals frames into that form and turns a byte stream back into checked raw frames, for every
//! kind of frame; what the frames mean is the business of the layers on top:
//!
//! - [`wire`]: the sensor's points and pose frames (PROTOCOL.md, versions 1 and 2), and
//!   [`receiver`], which maps their points into one world frame;
//! - [`frame`]: the header the host and a mapping device share (version, kind, session, boot,
//!   number), with [`uplink`] (host to device: the stream carried, requests) and [`downlink`]
//!   (device to host: the map, progress, timing, answers) on it.
//!
//! All of it is `no_std`, allocates nothing and never panics on what the line brings.

pub mod cobs;
pub mod crc32;
pub mod downlink;
pub mod frame;
pub mod framing;
pub mod receiver;
pub mod uplink;
pub mod wire;
