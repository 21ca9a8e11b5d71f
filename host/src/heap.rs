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

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

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
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
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
            p
        } else {
            // SAFETY: as above.
            let p = unsafe { System.realloc(ptr, layout, new_size) };
            if !p.is_null() {
                shrank(old - new_size);
            }
            p
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
