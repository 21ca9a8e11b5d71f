//! The frames a host and a mapping device exchange ([`super::uplink`], [`super::downlink`]):
//! one header, a payload by kind, the CRC-32, framed by [`super::framing`].
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 1 | version: [`super::downlink::DOWNLINK_VERSION`] or [`super::uplink::UPLINK_VERSION`] |
//! | 1 | 1 | kind, by direction |
//! | 2 | 4 | session u32: the host's identifier of the session (`0`: none) |
//! | 6 | 4 | boot u32: the device's identifier of its boot (`0` from a host that does not know it yet) |
//! | 10 | 4 | number u32: by kind (a sequence number, a carry frame's or a query's number) |
//! | 14 | n | payload |
//! | 14 + n | 4 | CRC-32 of every byte before it |
//!
//! Why a session and a boot in every frame: a device that was not reset would otherwise answer
//! a new host with the map of the last one, and a device that reset mid-session would go on
//! with a map that lacks the stream's beginning, both with intact CRCs. With them, the host
//! takes only frames of its own session from the boot that started it, and notices a reboot at
//! the first frame after it.
//!
//! [`LinkFrame`] is a view over a raw frame's bytes (smoltcp's wire-view style): checked once
//! by [`LinkFrame::new_checked`], after which no accessor fails.

use super::framing::{self, CRC_LEN, FramingError};

/// Bytes of the header.
pub const HEADER_LEN: usize = 14;
/// The longest payload of any kind in either direction (a carry frame's).
pub const MAX_PAYLOAD_LEN: usize = super::uplink::MAX_CARRIED;
/// The longest raw frame.
pub const MAX_RAW_LEN: usize = HEADER_LEN + MAX_PAYLOAD_LEN + CRC_LEN;

mod field {
    use core::ops::Range;
    pub const VERSION: usize = 0;
    pub const KIND: usize = 1;
    pub const SESSION: Range<usize> = 2..6;
    pub const BOOT: Range<usize> = 6..10;
    pub const NUMBER: Range<usize> = 10..14;
    pub const PAYLOAD: usize = 14;
}

/// Why a host-device frame was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError {
    /// Not a frame: oversized, malformed, short, or its CRC fails.
    Framing(FramingError),
    /// Not this direction's version: another protocol version, or the other direction's frame.
    Version(u8),
    /// A kind, entity kind, layout or flag this version does not define.
    Code(u8),
    /// The payload is not the length its kind has.
    Length { kind: u8, got: usize },
    /// A value no frame of its kind carries (a non-finite centre, a negative weight, a zero
    /// session where one is needed).
    Value,
    /// The output buffer is too small, or a payload too long for a frame.
    BufferTooSmall,
}

impl From<FramingError> for LinkError {
    fn from(e: FramingError) -> Self {
        Self::Framing(e)
    }
}

impl core::fmt::Display for LinkError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Framing(e) => write!(f, "{e}"),
            Self::Version(v) => write!(f, "protocol version 0x{v:02x}"),
            Self::Code(c) => write!(f, "undefined code {c}"),
            Self::Length { kind, got } => write!(f, "kind {kind} with a payload of {got} bytes"),
            Self::Value => write!(f, "a value no frame carries"),
            Self::BufferTooSmall => write!(f, "buffer too small"),
        }
    }
}

impl core::error::Error for LinkError {}

/// Who a frame is from and to, and its number: the header's fields but the version.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Address {
    /// The host's session (`0`: none).
    pub session: u32,
    /// The device's boot (`0`: not known to a host).
    pub boot: u32,
}

/// A view over a raw host-device frame (its CRC included).
#[derive(Clone, Copy, Debug)]
pub struct LinkFrame<T: AsRef<[u8]>> {
    buffer: T,
}

fn u32_at(bytes: &[u8], range: core::ops::Range<usize>) -> u32 {
    let mut b = [0u8; 4];
    if let Some(src) = bytes.get(range) {
        for (slot, v) in b.iter_mut().zip(src) {
            *slot = *v;
        }
    }
    u32::from_le_bytes(b)
}

impl<T: AsRef<[u8]>> LinkFrame<T> {
    /// A view without checks: accessors read zeros where bytes are missing.
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// A view of a raw frame of version `version` whose CRC matches.
    pub fn new_checked(buffer: T, version: u8) -> Result<Self, LinkError> {
        framing::check_crc(buffer.as_ref(), HEADER_LEN)?;
        let frame = Self::new_unchecked(buffer);
        if frame.version() != version {
            return Err(LinkError::Version(frame.version()));
        }
        Ok(frame)
    }

    pub fn version(&self) -> u8 {
        self.buffer
            .as_ref()
            .get(field::VERSION)
            .copied()
            .unwrap_or(0)
    }

    pub fn kind(&self) -> u8 {
        self.buffer.as_ref().get(field::KIND).copied().unwrap_or(0)
    }

    pub fn session(&self) -> u32 {
        u32_at(self.buffer.as_ref(), field::SESSION)
    }

    pub fn boot(&self) -> u32 {
        u32_at(self.buffer.as_ref(), field::BOOT)
    }

    pub fn address(&self) -> Address {
        Address {
            session: self.session(),
            boot: self.boot(),
        }
    }

    pub fn number(&self) -> u32 {
        u32_at(self.buffer.as_ref(), field::NUMBER)
    }

    /// The bytes between the header and the CRC.
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        b.get(field::PAYLOAD..b.len().saturating_sub(CRC_LEN))
            .unwrap_or(&[])
    }

    /// A reader of the payload for a kind whose payload is `len` bytes.
    pub fn payload_of(&self, len: usize) -> Result<Payload<'_>, LinkError> {
        let payload = self.payload();
        if payload.len() != len {
            return Err(LinkError::Length {
                kind: self.kind(),
                got: payload.len(),
            });
        }
        Ok(Payload {
            buf: payload,
            at: 0,
        })
    }
}

/// A frame being written: header, then payload fields in order, then [`Emitter::seal`].
#[derive(Debug)]
pub struct Emitter {
    raw: [u8; MAX_RAW_LEN],
    at: usize,
    /// A field did not fit: sealing fails rather than sending a short frame.
    overflow: bool,
}

impl Emitter {
    pub fn new(version: u8, kind: u8, to: Address, number: u32) -> Self {
        let mut e = Self {
            raw: [0; MAX_RAW_LEN],
            at: 0,
            overflow: false,
        };
        e.put(&[version, kind]);
        e.put(&to.session.to_le_bytes());
        e.put(&to.boot.to_le_bytes());
        e.put(&number.to_le_bytes());
        e
    }

    pub fn put(&mut self, bytes: &[u8]) -> &mut Self {
        match self.raw.get_mut(self.at..self.at + bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.at += bytes.len();
            }
            None => self.overflow = true,
        }
        self
    }

    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.put(&[v])
    }

    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.put(&v.to_le_bytes())
    }

    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.put(&v.to_le_bytes())
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.put(&v.to_le_bytes())
    }

    pub fn f32(&mut self, v: f32) -> &mut Self {
        self.put(&v.to_le_bytes())
    }

    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.put(&v.to_le_bytes())
    }

    /// The frame, CRC added, COBS-encoded and delimited into `out`; the bytes to send.
    pub fn seal(&mut self, out: &mut [u8]) -> Result<usize, LinkError> {
        if self.overflow {
            return Err(LinkError::BufferTooSmall);
        }
        framing::seal(&mut self.raw, self.at, out).ok_or(LinkError::BufferTooSmall)
    }
}

/// Reads a payload's fields in order; its length was checked against its kind's, so a read
/// past it (a bug, never the line's doing) reports the payload's length.
#[derive(Debug)]
pub struct Payload<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> Payload<'a> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], LinkError> {
        let got = self.buf.len();
        let bytes = self
            .buf
            .get(self.at..self.at + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or(LinkError::Length { kind: 0xFF, got })?;
        self.at += N;
        Ok(bytes)
    }

    pub fn u8(&mut self) -> Result<u8, LinkError> {
        let [b] = self.take::<1>()?;
        Ok(b)
    }

    pub fn u16(&mut self) -> Result<u16, LinkError> {
        Ok(u16::from_le_bytes(self.take()?))
    }

    pub fn u32(&mut self) -> Result<u32, LinkError> {
        Ok(u32::from_le_bytes(self.take()?))
    }

    pub fn u64(&mut self) -> Result<u64, LinkError> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    pub fn f32(&mut self) -> Result<f32, LinkError> {
        Ok(f32::from_le_bytes(self.take()?))
    }

    pub fn f64(&mut self) -> Result<f64, LinkError> {
        Ok(f64::from_le_bytes(self.take()?))
    }

    /// A boolean byte: `0` or `1`, anything else undefined.
    pub fn flag(&mut self) -> Result<bool, LinkError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(LinkError::Code(other)),
        }
    }

    /// The rest of the payload.
    pub fn rest(&mut self) -> &'a [u8] {
        let rest = self.buf.get(self.at..).unwrap_or(&[]);
        self.at = self.buf.len();
        rest
    }
}
