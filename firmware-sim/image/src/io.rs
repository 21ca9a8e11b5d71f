//! Semihosting file I/O: the capture comes in, the map and the report go out. Raw syscalls and
//! hand-made decimal digits, so no `core::fmt` (and none of its panic paths) is linked.

use cortex_m_semihosting::{nr, syscall};
use mema_core::rng::{Pcg32, index_below, stream_rng};
use mema_firmware::source::{ByteSource, Delivery};

fn open(path_nul: &[u8], mode: usize) -> Option<usize> {
    let len = path_nul.len().checked_sub(1)?;
    // SAFETY: SYS_OPEN reads `len` bytes of a NUL-terminated path that outlives the call.
    let fd = unsafe { syscall!(OPEN, path_nul.as_ptr(), mode, len) };
    (fd as isize != -1).then_some(fd)
}

fn close(fd: usize) {
    // SAFETY: SYS_CLOSE takes a handle by value.
    unsafe {
        syscall!(CLOSE, fd);
    }
}

fn write(fd: usize, bytes: &[u8]) -> bool {
    // SAFETY: SYS_WRITE reads `bytes.len()` bytes from a live slice; it returns the bytes not written.
    unsafe { syscall!(WRITE, fd, bytes.as_ptr(), bytes.len()) == 0 }
}

/// Writes what `produce` hands over to a new file at `path_nul` (QEMU's working directory).
pub fn write_file(path_nul: &[u8], produce: impl FnOnce(&mut dyn FnMut(&[u8]))) -> bool {
    let Some(fd) = open(path_nul, nr::open::W_TRUNC_BINARY) else {
        return false;
    };
    let mut ok = true;
    // Piece by piece as `produce` hands them over: no buffer ever holds the whole file.
    produce(&mut |piece| ok &= write(fd, piece));
    close(fd);
    ok
}

/// Reads up to `buf.len()` bytes of the file at `path_nul`; `None` if it cannot be opened.
pub fn read_file(path_nul: &[u8], buf: &mut [u8]) -> Option<usize> {
    let fd = open(path_nul, nr::open::R_BINARY)?;
    // SAFETY: SYS_READ writes at most `buf.len()` bytes into a live slice; it returns the
    // number of bytes *not* read.
    let not_read = unsafe { syscall!(READ, fd, buf.as_mut_ptr(), buf.len()) };
    close(fd);
    Some(buf.len().saturating_sub(not_read))
}

/// Writes the pieces to the host's stdout.
pub fn print(pieces: &[&[u8]]) {
    if let Some(fd) = open(b":tt\0", nr::open::W_TRUNC) {
        for p in pieces {
            write(fd, p);
        }
    }
}

/// `value` in decimal, in `buf`.
// Digits in u32 where the value fits (all of the report's do), nine at a time by a u64
// division above: u64 arithmetic by a constant, unrolled over the buffer and over the report's
// 27 values, was 1.5 KB of a 64 KiB part's flash.
#[inline(never)]
pub fn decimal(mut value: u64, buf: &mut [u8; 20]) -> &[u8] {
    let mut at = buf.len();
    loop {
        // The low nine digits of a value past u32, zero-padded; else all of it.
        let (mut digits, width, more) = match u32::try_from(value) {
            Ok(v) => (v, 1, false),
            Err(_) => ((value % 1_000_000_000) as u32, 9, true),
        };
        value /= 1_000_000_000;
        let end = at;
        loop {
            at = at.wrapping_sub(1);
            if let Some(d) = buf.get_mut(at) {
                *d = b'0' + (digits % 10) as u8;
            }
            digits /= 10;
            if digits == 0 && end.wrapping_sub(at) >= width {
                break;
            }
        }
        if !more {
            break;
        }
    }
    buf.get(at..).unwrap_or(&[])
}

/// The capture file read as a UART delivers it: 1..=256 bytes per interrupt, seeded sizes.
pub struct SemihostingUart {
    fd: usize,
    rng: Pcg32,
    done: bool,
}

impl SemihostingUart {
    pub fn open(path_nul: &[u8], seed: u64) -> Option<Self> {
        Some(Self {
            fd: open(path_nul, nr::open::R_BINARY)?,
            rng: stream_rng(seed, 0x55),
            done: false,
        })
    }
}

impl ByteSource for SemihostingUart {
    type Error = core::convert::Infallible;

    fn deliver(&mut self, buf: &mut [u8]) -> Result<Delivery, Self::Error> {
        if self.done {
            return Ok(Delivery::End);
        }
        let want = (1 + index_below(&mut self.rng, 256)).min(buf.len());
        let Some(dst) = buf.get_mut(..want) else {
            return Ok(Delivery::End);
        };
        // SAFETY: SYS_READ writes at most `dst.len()` bytes into a live slice; it returns the
        // number of bytes *not* read.
        let not_read = unsafe { syscall!(READ, self.fd, dst.as_mut_ptr(), dst.len()) };
        let got = dst.len().saturating_sub(not_read);
        if got == 0 {
            self.done = true;
            close(self.fd);
            return Ok(Delivery::End);
        }
        Ok(Delivery::Bytes(got))
    }
}
