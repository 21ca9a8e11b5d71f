//! CDR, as ROS 2 serializes a message (OMG CDR, "XCDR1" plain), read from an untrusted byte
//! slice.
//!
//! The layout, which is all the reader assumes:
//! - a 4-byte encapsulation header: a big-endian u16 id, `0x0000` (CDR, big-endian body) or
//!   `0x0001` (CDR_LE, little-endian body), then two option bytes, ignored;
//! - then the fields in declaration order, each primitive aligned to its own size (1, 4 or 8)
//!   relative to the start of the body, the byte after the header;
//! - a string is a u32 length counting its terminating NUL, the bytes and the NUL (a length
//!   of 0 is read as the empty string, as some writers emit it);
//! - a sequence is a u32 element count, then the elements.
//!
//! The contract: every read checks the bytes left before it touches them, and a count from the
//! message is checked against the bytes left (times the least each element takes) before
//! anything is allocated or looped over for it. No input makes a reader panic; each failure is
//! a [`CdrError`] naming the field and the byte offset from the start of the message.

/// Why a message's bytes are not the CDR a field needs.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum CdrError {
    /// Fewer than the 4 bytes of the encapsulation header.
    #[error("{len} bytes, too short for CDR's 4-byte encapsulation header")]
    NoHeader { len: usize },
    /// An encapsulation other than plain CDR (parameter lists, XCDR2).
    #[error(
        "encapsulation {id:#06x}; only plain CDR is read (0x0000 big-endian, 0x0001 little-endian)"
    )]
    Encapsulation { id: u16 },
    /// The message ends inside a field.
    #[error("byte {at}: {what} needs {need} bytes, {left} are left")]
    Truncated {
        what: &'static str,
        at: usize,
        need: usize,
        left: usize,
    },
    /// A sequence or string whose count the bytes left cannot hold.
    #[error("byte {at}: {what} declares {count} elements, more than the {left} bytes left hold")]
    Count {
        what: &'static str,
        at: usize,
        count: u64,
        left: usize,
    },
    /// A string without its NUL, or not UTF-8.
    #[error("byte {at}: {what} is not a NUL-terminated UTF-8 string")]
    BadString { what: &'static str, at: usize },
}

/// A reading position in one CDR message.
pub(super) struct Cdr<'a> {
    /// The bytes after the encapsulation header.
    body: &'a [u8],
    /// The next byte to read, from the start of `body`.
    at: usize,
    little: bool,
}

/// The header's bytes before the body, for offsets counted from the start of the message.
const HEADER: usize = 4;

impl<'a> Cdr<'a> {
    /// Checks the encapsulation header.
    pub fn new(message: &'a [u8]) -> Result<Self, CdrError> {
        let Some((&[id_hi, id_lo, _, _], body)) = message.split_first_chunk::<HEADER>() else {
            return Err(CdrError::NoHeader { len: message.len() });
        };
        let little = match u16::from_be_bytes([id_hi, id_lo]) {
            0x0000 => false,
            0x0001 => true,
            id => return Err(CdrError::Encapsulation { id }),
        };
        Ok(Self {
            body,
            at: 0,
            little,
        })
    }

    /// Whether the body is little-endian.
    #[cfg(test)]
    pub fn little_endian(&self) -> bool {
        self.little
    }

    /// Bytes not yet read.
    pub fn left(&self) -> usize {
        self.body.len().saturating_sub(self.at)
    }

    fn truncated(&self, what: &'static str, need: usize) -> CdrError {
        CdrError::Truncated {
            what,
            at: self.at + HEADER,
            need,
            left: self.left(),
        }
    }

    /// Skips the padding before a primitive of `size` bytes.
    fn align(&mut self, size: usize, what: &'static str) -> Result<(), CdrError> {
        let pad = (size - self.at % size) % size;
        if pad > self.left() {
            return Err(self.truncated(what, pad));
        }
        self.at += pad;
        Ok(())
    }

    /// The next `n` bytes, unaligned.
    pub fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let end = self.at.checked_add(n);
        match end.and_then(|end| self.body.get(self.at..end)) {
            Some(bytes) => {
                self.at += n;
                Ok(bytes)
            }
            None => Err(self.truncated(what, n)),
        }
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        self.align(N, what)?;
        let bytes = self.take(N, what)?;
        bytes
            .first_chunk::<N>()
            .copied()
            .ok_or_else(|| self.truncated(what, N))
    }

    pub fn u8(&mut self, what: &'static str) -> Result<u8, CdrError> {
        Ok(self.array::<1>(what)?[0])
    }

    pub fn bool(&mut self, what: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(what)? != 0)
    }

    pub fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        let b = self.array::<4>(what)?;
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    pub fn i32(&mut self, what: &'static str) -> Result<i32, CdrError> {
        Ok(self.u32(what)? as i32)
    }

    pub fn f64(&mut self, what: &'static str) -> Result<f64, CdrError> {
        let b = self.array::<8>(what)?;
        Ok(if self.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }

    /// A sequence's element count, checked: `count * least` bytes must be left, `least` being
    /// the fewest bytes one element takes.
    pub fn count(&mut self, least: usize, what: &'static str) -> Result<usize, CdrError> {
        let count = self.u32(what)?;
        let left = self.left();
        let fits = usize::try_from(count)
            .ok()
            .filter(|&n| n.checked_mul(least.max(1)).is_some_and(|b| b <= left));
        fits.ok_or(CdrError::Count {
            what,
            at: self.at + HEADER - 4,
            count: u64::from(count),
            left,
        })
    }

    /// A `string`.
    pub fn string(&mut self, what: &'static str) -> Result<&'a str, CdrError> {
        let len = self.count(1, what)?;
        let at = self.at + HEADER;
        let bytes = self.take(len, what)?;
        let text = match bytes.split_last() {
            None => &[][..],
            Some((0, text)) => text,
            Some(_) => return Err(CdrError::BadString { what, at }),
        };
        std::str::from_utf8(text).map_err(|_| CdrError::BadString { what, at })
    }

    /// A `sequence<uint8>`: its bytes, borrowed.
    pub fn bytes(&mut self, what: &'static str) -> Result<&'a [u8], CdrError> {
        let len = self.count(1, what)?;
        self.take(len, what)
    }
}

/// A ROS time (`builtin_interfaces/msg/Time`): seconds and nanoseconds since the epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Stamp {
    pub sec: i32,
    pub nanosec: u32,
}

impl Stamp {
    /// Nanoseconds since the epoch, for ordering and messages.
    pub fn nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

impl std::fmt::Display for Stamp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{:09} s", self.sec, self.nanosec)
    }
}

/// A `std_msgs/msg/Header`: its stamp and frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    pub stamp: Stamp,
    pub frame_id: String,
}

impl Cdr<'_> {
    pub fn header(&mut self) -> Result<Header, CdrError> {
        let sec = self.i32("header.stamp.sec")?;
        let nanosec = self.u32("header.stamp.nanosec")?;
        let frame_id = self.string("header.frame_id")?.to_owned();
        Ok(Header {
            stamp: Stamp { sec, nanosec },
            frame_id,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_align_to_their_size_after_the_header() {
        // CDR_LE: u8 1, pad 3, u32 2, pad 0, f64 at body offset 8.
        let mut m = vec![0, 1, 0, 0, 1, 0xee, 0xee, 0xee, 2, 0, 0, 0];
        m.extend_from_slice(&1.5f64.to_le_bytes());
        let mut c = Cdr::new(&m).unwrap();
        assert!(c.little_endian());
        assert_eq!(c.u8("a").unwrap(), 1);
        assert_eq!(c.u32("b").unwrap(), 2);
        assert_eq!(c.f64("c").unwrap(), 1.5);
        assert_eq!(c.left(), 0);
        assert!(matches!(c.u8("d"), Err(CdrError::Truncated { at: 20, .. })));
    }

    #[test]
    fn big_endian_strings_and_bad_counts() {
        let mut m = vec![0, 0, 0, 0, 0, 0, 0, 3, b'a', b'b', 0];
        let mut c = Cdr::new(&m).unwrap();
        assert_eq!(c.string("s").unwrap(), "ab");
        // No NUL.
        m[10] = b'c';
        assert!(matches!(
            Cdr::new(&m).unwrap().string("s"),
            Err(CdrError::BadString { .. })
        ));
        // A count past the bytes left is refused before any allocation.
        let huge = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff];
        assert!(matches!(
            Cdr::new(&huge).unwrap().bytes("data"),
            Err(CdrError::Count { .. })
        ));
        assert!(matches!(
            Cdr::new(&[0, 2, 0, 0]),
            Err(CdrError::Encapsulation { id: 2 })
        ));
        assert!(matches!(Cdr::new(&[0]), Err(CdrError::NoHeader { len: 1 })));
    }
}
