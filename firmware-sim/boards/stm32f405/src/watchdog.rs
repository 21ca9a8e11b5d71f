//! The independent watchdog: if the main loop stops passing (a fault it never returns from, a
//! loop that never ends), the part resets in about two seconds, boots into no session, and the
//! host, which sees the boot change, starts its session again. The loop feeds it on every pass;
//! it passes at least at every SysTick wrap (the timer's interrupt ends each `wfi`), 0.1 s at
//! 168 MHz and 1 s on the 16 MHz oscillator, and its longest piece of work (finishing the map)
//! takes a fraction of a second. QEMU's `netduinoplus2` does not model the IWDG: there the
//! writes go nowhere.

use stm32f4::stm32f405 as pac;

/// Watchdog counts before it resets the part: the 32 kHz LSI divided by 64 is 500 a second.
const RELOAD: u16 = 1_000;

pub fn start(iwdg: &pac::IWDG) {
    iwdg.kr().write(|w| w.key().unlock());
    iwdg.pr().write(|w| w.pr().divide_by64());
    iwdg.rlr().write(|w| w.rl().set(RELOAD));
    iwdg.kr().write(|w| w.key().start());
}

/// Tells the watchdog the loop is alive.
pub fn feed() {
    // SAFETY: writing the feed key to IWDG_KR has no effect but reloading the counter; nothing
    // else writes the register after `start`.
    let iwdg = unsafe { &*pac::IWDG::ptr() };
    iwdg.kr().write(|w| w.key().feed());
}
