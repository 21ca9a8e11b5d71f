//! What the work costs, in SysTick ticks of the core clock: the main loop's ticks and downlink,
//! and the receive interrupt, kept apart so that an interrupt taken while the main loop works is
//! counted once. The clock and its calibration are the 64 KiB image's (`systick.rs`, shared as
//! a file): under QEMU's `-icount shift=0` they turn ticks into instructions.

use core::cell::Cell;

use cortex_m::interrupt::Mutex;
use mema_core::link::downlink::DeviceTiming;

use crate::systick::{Calibration, now};

/// Ticks spent in the receive interrupt.
static IN_INTERRUPT: Mutex<Cell<u64>> = Mutex::new(Cell::new(0));

pub fn interrupt_ticks() -> u64 {
    cortex_m::interrupt::free(|cs| IN_INTERRUPT.borrow(cs).get())
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

    /// Other work of the main loop (the carrier, the downlink).
    pub fn other<T>(&mut self, f: impl FnOnce() -> T) -> T {
        self.timed(f).0
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
