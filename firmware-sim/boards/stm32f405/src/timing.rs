//! What the work costs: SysTick ticks of the core clock (under QEMU's `-icount shift=0`,
//! instructions, through the 64 KiB image's calibration in `systick.rs`, shared as a file) and,
//! on silicon, the DWT's cycle count, for the main loop's ticks and downlink and for the receive
//! interrupt, kept apart so that an interrupt taken while the main loop works is counted once.

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::interrupt::Mutex;
use cortex_m::peripheral::DWT;
use mema_core::link::downlink::DeviceTiming;

use mema_firmware::cortex_m::systick::{Calibration, now};

/// Ticks spent in the receive interrupt.
static IN_INTERRUPT: Mutex<Cell<u64>> = Mutex::new(Cell::new(0));
/// Whether the part's cycle counter runs (QEMU models none: then nothing reads it, so the
/// instruction counts taken there carry no cost of it), and the interrupt's cycles (wrapping).
static CYCLES_ON: AtomicBool = AtomicBool::new(false);
static INTERRUPT_CYCLES: AtomicU32 = AtomicU32::new(0);

/// Starts the cycle counter where the part has one.
pub fn start_cycles(dcb: &mut cortex_m::peripheral::DCB, dwt: &mut DWT) {
    if DWT::has_cycle_counter() {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        CYCLES_ON.store(true, Ordering::Relaxed);
    }
}

/// The cycle counter, where it runs.
fn cycles() -> Option<u32> {
    CYCLES_ON.load(Ordering::Relaxed).then(DWT::cycle_count)
}

pub fn interrupt_ticks() -> u64 {
    cortex_m::interrupt::free(|cs| IN_INTERRUPT.borrow(cs).get())
}

/// Times the receive interrupt from its start to the end of its scope.
pub struct InInterrupt(u64, Option<u32>);

impl InInterrupt {
    pub fn start() -> Self {
        Self(now(), cycles())
    }
}

impl Drop for InInterrupt {
    fn drop(&mut self) {
        let dt = now().saturating_sub(self.0);
        cortex_m::interrupt::free(|cs| {
            let spent = IN_INTERRUPT.borrow(cs);
            spent.set(spent.get() + dt);
        });
        if let (Some(c0), Some(c1)) = (self.1, cycles()) {
            // The 32-bit counter wraps every 25 s at 168 MHz; an interrupt takes microseconds.
            INTERRUPT_CYCLES.fetch_add(c1.wrapping_sub(c0), Ordering::Relaxed);
        }
    }
}

/// The main loop's work, interrupts taken during it left out (they are counted on their own).
#[derive(Default)]
pub struct Work {
    ticks: u64,
    cycles: u64,
    longest_tick: u64,
    /// The interrupt's cycles (wrapping) when the cycles were last reported.
    interrupt_cycles: u64,
    interrupt_cycles_seen: u32,
}

impl Work {
    fn timed<T>(&mut self, f: impl FnOnce() -> T) -> (T, u64) {
        let (t0, i0) = (now(), interrupt_ticks());
        let c0 = cycles().map(|c| (c, INTERRUPT_CYCLES.load(Ordering::Relaxed)));
        let out = f();
        let dt = (now() - t0).saturating_sub(interrupt_ticks() - i0);
        if let (Some((c0, ic0)), Some(c1)) = (c0, cycles()) {
            // A piece of work is under a millisecond, far from the counter's wrap.
            let ic1 = INTERRUPT_CYCLES.load(Ordering::Relaxed);
            let dc = c1.wrapping_sub(c0).saturating_sub(ic1.wrapping_sub(ic0));
            self.cycles += u64::from(dc);
        }
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

    /// The interrupt's cycles so far, accumulated past the wrap of their 32-bit count (called
    /// at least once a wrap: every pass of the main loop).
    pub fn note_interrupt_cycles(&mut self) {
        let now = INTERRUPT_CYCLES.load(Ordering::Relaxed);
        self.interrupt_cycles += u64::from(now.wrapping_sub(self.interrupt_cycles_seen));
        self.interrupt_cycles_seen = now;
    }

    /// The account the timing frame carries, with the deepest the stack went and the bytes
    /// the ring and the UART lost.
    pub fn report(
        &self,
        calibration: Calibration,
        stack_bytes: usize,
        (ring_overruns, line_overruns): (u32, u32),
    ) -> DeviceTiming {
        let interrupt = interrupt_ticks();
        let interrupt_cycles = self.interrupt_cycles
            + u64::from(
                INTERRUPT_CYCLES
                    .load(Ordering::Relaxed)
                    .wrapping_sub(self.interrupt_cycles_seen),
            );
        DeviceTiming {
            busy_ticks: self.ticks + interrupt,
            interrupt_ticks: interrupt,
            longest_tick: self.longest_tick,
            calib_ticks: calibration.ticks,
            calib_insns: calibration.insns,
            stack_bytes: stack_bytes as u64,
            busy_cycles: if cycles().is_some() {
                self.cycles + interrupt_cycles
            } else {
                0
            },
            ring_overruns,
            line_overruns,
        }
    }
}
