//! A counting global allocator: the live and the peak heap bytes of the process.
//!
//! `mema bench` reports the pipeline's memory from it. The kernel's peak resident size (VmHWM)
//! is reported too, but it includes the binary, the threads' stacks and pages the allocator
//! keeps after a free, about 4.7 MB before anything is read; next to a 0.1 MB cloud that says
//! nothing about the pipeline. The heap counted here is what the pipeline itself holds.
//!
//! The `mema` binary installs it (`main.rs`); a program that does not has zero counts, which
//! [`counting`] tells apart. The figures are the sizes asked for: the allocator's own overhead
//! (chunk headers, rounding) is not in them. Each allocation costs two relaxed atomic updates.
//!
//! It also turns an allocation that fails into a one-line error with exit status 1, where Rust
//! would print a backtrace (under RUST_BACKTRACE) and abort with 134: a robot's supervisor
//! reads one line and a status. Allocations that may fail by design, the readers' reservations
//! sized by a file's header, run inside [`fallible`] and get the null that becomes their
//! `OutOfMemory` error.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// Heap bytes the default map holds per point at its peak, above the points themselves:
/// measured on office1 (254,456 points) as 63 bytes a point of resident memory above the
/// process's start with surface following, 27 without it or for `--paper` (docs/command-line.md, on memory).
pub const MAP_BYTES_PER_POINT: usize = 64;

thread_local! {
    /// Depth of [`fallible`] sections on this thread (const, no destructor: safe to read from
    /// inside the allocator at any time).
    static FALLIBLE: Cell<u32> = const { Cell::new(0) };
}

/// Runs `f` with allocation failures returned to the caller (as null, so `try_reserve` reports
/// them) instead of ending the process.
pub fn fallible<T>(f: impl FnOnce() -> T) -> T {
    FALLIBLE.with(|c| c.set(c.get() + 1));
    let out = f();
    FALLIBLE.with(|c| c.set(c.get().saturating_sub(1)));
    out
}

/// A failed allocation outside [`fallible`]: one line on stderr and exit status 1. Nothing here
/// allocates: the message is assembled on the stack, and `_exit` runs no handler that could.
#[cold]
fn out_of_memory(bytes: usize) -> ! {
    let mut line = [0u8; 256];
    let mut w = &mut line[..];
    let _ = writeln!(
        w,
        "mema: out of memory: {bytes} more bytes could not be had (a map needs about \
         {MAP_BYTES_PER_POINT} bytes per point of the cloud beside the points' 12)"
    );
    let used = 256 - w.len();
    let _ = std::io::stderr().write_all(&line[..used]);
    // SAFETY: `_exit` ends the process at once; it is async-signal-safe and touches no Rust
    // state, so it is sound from inside the allocator, on any thread.
    unsafe { libc::_exit(1) }
}

fn checked(p: *mut u8, layout: &Layout) -> *mut u8 {
    if p.is_null() && FALLIBLE.try_with(Cell::get).unwrap_or(0) == 0 {
        out_of_memory(layout.size());
    }
    p
}

/// The system allocator, counted.
#[derive(Debug, Default, Clone, Copy)]
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = LIVE.fetch_add(bytes, Relaxed) + bytes;
    PEAK.fetch_max(now, Relaxed);
}

fn shrank(bytes: usize) {
    LIVE.fetch_sub(bytes, Relaxed);
}

// SAFETY: every call is forwarded unchanged to `System`, which upholds the `GlobalAlloc`
// contract; the counting around it touches only two atomics and never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's guarantees on `layout` are passed on as they are.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        checked(p, &layout)
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        checked(p, &layout)
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator, that is from `System`, with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old {
            // A growing realloc may copy, so for a moment both blocks count: a Vec that
            // doubles shows the peak it can really cause.
            grew(new_size);
            // SAFETY: `ptr` and `layout` as for `dealloc`; `new_size` as the caller checked.
            let p = unsafe { System.realloc(ptr, layout, new_size) };
            shrank(if p.is_null() { new_size } else { old });
            checked(p, &layout)
        } else {
            // SAFETY: as above.
            let p = unsafe { System.realloc(ptr, layout, new_size) };
            if !p.is_null() {
                shrank(old - new_size);
            }
            checked(p, &layout)
        }
    }
}

/// Heap bytes live now.
pub fn live() -> usize {
    LIVE.load(Relaxed)
}

/// The most heap bytes live at once since the start, or since the last [`reset_peak`].
pub fn peak() -> usize {
    PEAK.load(Relaxed)
}

/// Starts a new peak from the bytes live now, and returns them.
pub fn reset_peak() -> usize {
    let now = live();
    PEAK.store(now, Relaxed);
    now
}

/// Whether [`Counting`] is this program's allocator: any program has allocated by the time it
/// asks, so a zero peak means nothing was counted.
pub fn counting() -> bool {
    PEAK.load(Relaxed) > 0
}
