//! A painted stack: every word between the end of the statics and (just below) the current
//! stack pointer is set to a pattern; the lowest word no longer holding it is how deep the
//! stack went. cortex-m-rt puts the stack at the top of RAM, growing down towards `__sheap`
//! (the end of .bss and .uninit).

const PAINT: u32 = 0xC0FF_EE11;
/// Words left unpainted below the stack pointer, for `paint`'s own frame.
const MARGIN_WORDS: usize = 64;

unsafe extern "C" {
    static mut __sheap: u32;
    static _stack_start: u32;
}

fn bounds() -> (*mut u32, *mut u32) {
    let low = &raw mut __sheap;
    let top = (&raw const _stack_start).cast_mut();
    (low, top)
}

/// Paints the free stack.
pub fn paint() {
    let (low, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let end = (sp / 4).saturating_sub(MARGIN_WORDS) * 4;
    let mut p = low;
    while (p as usize) < end {
        // SAFETY: [__sheap, sp - margin) is RAM that no live object occupies: the statics end at
        // __sheap (no heap is used) and the stack lives above sp.
        unsafe {
            p.write_volatile(PAINT);
            p = p.add(1);
        }
    }
}

/// Bytes of stack used since the last `paint`: from the top of RAM down to the lowest word
/// that lost the pattern.
pub fn high_water() -> usize {
    let (low, top) = bounds();
    let mut p = low;
    while (p as usize) < (top as usize) {
        // SAFETY: reads of RAM between __sheap and the top of the stack, word-aligned.
        let v = unsafe { p.read_volatile() };
        if v != PAINT {
            break;
        }
        // SAFETY: stays within RAM (bounded by `top`).
        p = unsafe { p.add(1) };
    }
    top as usize - p as usize
}
