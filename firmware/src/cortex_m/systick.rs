//! Time on a Cortex-M: SysTick on the core clock, the wraps of its 24-bit counter counted by
//! its exception, and a loop of known length that turns ticks into instructions (under QEMU's
//! `-icount shift=0` the clock counts instructions).

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;

/// SysTick's 24-bit counter wraps at this; its exception counts the wraps.
const RELOAD: u32 = 0x00FF_FFFF;
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Ticks since the timer started (wraps included).
pub fn now() -> u64 {
    loop {
        let before = WRAPS.load(Ordering::Relaxed);
        let current = SYST::get_current();
        if WRAPS.load(Ordering::Relaxed) == before {
            return u64::from(before) * u64::from(RELOAD + 1) + u64::from(RELOAD - current);
        }
    }
}

/// Runs `n` iterations of a two-instruction loop.
fn spin(n: u32) {
    if n == 0 {
        return;
    }
    // SAFETY: a register-only countdown loop; touches no memory and no flags outside it.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {0}, {0}, #1",
            "bne 2b",
            inout(reg) n => _,
            options(nomem, nostack),
        );
    }
}

/// The calibration: `insns` instructions of a known loop took `ticks`.
#[derive(Clone, Copy, Debug)]
pub struct Calibration {
    pub ticks: u64,
    pub insns: u64,
}

/// Starts SysTick on the core clock and times the calibration loop.
pub fn start(syst: &mut SYST) -> Calibration {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    // The counter reads 0 until its first reload: let it start before taking times.
    spin(1_000);
    let insns: u32 = 2_000_000;
    let t0 = now();
    spin(insns / 2);
    Calibration {
        ticks: now() - t0,
        insns: u64::from(insns),
    }
}
