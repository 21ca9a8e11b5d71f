//! What survives a reset: RAM the runtime does not initialise (`.uninit`), holding the boot
//! count and the session a host asked for. A host's start request resets the board into the
//! new session, so each session's map begins from a fresh boot; a reset nobody asked for (the
//! watchdog, a brown-out, a debugger) boots into no session, and the host, which sees the boot
//! change in the next frame, knows the map it was getting is gone.

use core::mem::MaybeUninit;
use core::ptr::{addr_of_mut, read_volatile, write_volatile};

/// Marks the words as written by this firmware rather than left over from power-up.
const MAGIC: u32 = 0x4D45_4D41;

/// `[magic, boot count, pending session, check]`.
#[unsafe(link_section = ".uninit.mema_retained")]
static mut RETAINED: MaybeUninit<[u32; 4]> = MaybeUninit::uninit();

fn check(boot: u32, session: u32) -> u32 {
    (boot ^ session.rotate_left(13) ^ MAGIC).wrapping_mul(0x9E37_79B1)
}

/// This boot's identifier (never 0) and the session it was reset into (`0`: none), which is
/// taken: a later reset nobody asked for boots into no session.
pub fn take_boot() -> (u32, u32) {
    // SAFETY: only this function and `reset_into` touch the words, from the main thread, with
    // volatile accesses (the words may hold anything at power-up: every pattern is a u32).
    unsafe {
        let words = addr_of_mut!(RETAINED).cast::<u32>();
        let [magic, boot, session, sum] = [0, 1, 2, 3].map(|i| read_volatile(words.add(i)));
        let valid = magic == MAGIC && sum == check(boot, session);
        // At power-up SRAM holds noise: the boot count starts from it, so two power-ups seldom
        // share an identifier; after a reset it counts on.
        let boot = if valid { boot } else { boot ^ sum }.wrapping_add(1).max(1);
        let session = if valid { session } else { 0 };
        for (i, v) in [MAGIC, boot, 0, check(boot, 0)].into_iter().enumerate() {
            write_volatile(words.add(i), v);
        }
        (boot, session)
    }
}

/// Resets the part into `session`: the next boot begins it.
pub fn reset_into(session: u32) -> ! {
    // SAFETY: as in `take_boot`.
    unsafe {
        let words = addr_of_mut!(RETAINED).cast::<u32>();
        let boot = read_volatile(words.add(1));
        for (i, v) in [MAGIC, boot, session, check(boot, session)]
            .into_iter()
            .enumerate()
        {
            write_volatile(words.add(i), v);
        }
    }
    cortex_m::peripheral::SCB::sys_reset()
}
