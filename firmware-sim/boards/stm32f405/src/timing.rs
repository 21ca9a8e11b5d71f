//! What the work costs, in SysTick ticks of the core clock: the main loop's ticks and downlink,
//! and the receive interrupt, kept apart so that an interrupt taken while the main loop works is
//! counted once. Under QEMU's `-icount shift=0` a calibration loop of known length turns ticks
//! into instructions, as the 64 KiB image's budget does.

use core::cell::Cell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::interrupt::Mutex;
use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;
use mema_core::downlink::DeviceTiming;

/// SysTick's 24-bit counter wraps at this; its exception counts the wraps.
const RELOAD: u32 = 0x00FF_FFFF;
static WRAPS: AtomicU32 = AtomicU32::new(0);
/// Ticks spent in the receive interrupt.
static IN_INTERRUPT: Mutex<Cell<u64>> = Mutex::new(Cell::new(0));

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

pub fn interrupt_ticks() -> u64 {
    cortex_m::interrupt::free(|cs| IN_INTERRUPT.borrow(cs).get())
}

/// The calibration: `insns` instructions of a known loop took `ticks`.
#[derive(Clone, Copy)]
pub struct Calibration {
    ticks: u64,
    insns: u64,
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

/// Times the receive interrupt from its start to the end of its scope.
pub struct InInterrupt(u64);

impl InInterrupt {
    pub fn start() -> Self {
        Self(now())
    }
}

impl Drop for InInterrupt {
    fn drop(&mut self) {
        let dt = now().saturating_sub(self.0);
        cortex_m::interrupt::free(|cs| {
            let spent = IN_INTERRUPT.borrow(cs);
            spent.set(spent.get() + dt);
        });
    }
}

/// The main loop's work, interrupts taken during it left out (they are counted on their own).
#[derive(Default)]
pub struct Work {
    ticks: u64,
    longest_tick: u64,
}

impl Work {
    fn timed<T>(&mut self, f: impl FnOnce() -> T) -> (T, u64) {
        let (t0, i0) = (now(), interrupt_ticks());
        let out = f();
        let dt = (now() - t0).saturating_sub(interrupt_ticks() - i0);
        self.ticks += dt;
        (out, dt)
    }

    /// One tick of the firmware.
    pub fn tick(&mut self, f: impl FnOnce()) {
        let ((), dt) = self.timed(f);
        self.longest_tick = self.longest_tick.max(dt);
    }

    /// Other work of the main loop (the downlink).
    pub fn other(&mut self, f: impl FnOnce()) {
        self.timed(f);
    }

    /// The account the timing frame carries, with the deepest the stack went.
    pub fn report(&self, calibration: Calibration, stack_bytes: usize) -> DeviceTiming {
        let interrupt = interrupt_ticks();
        DeviceTiming {
            busy_ticks: self.ticks + interrupt,
            interrupt_ticks: interrupt,
            longest_tick: self.longest_tick,
            calib_ticks: calibration.ticks,
            calib_insns: calibration.insns,
            stack_bytes: stack_bytes as u64,
        }
    }
}
