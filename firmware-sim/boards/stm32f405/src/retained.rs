//! What survives a reset: RAM the runtime does not initialise (`.uninit`), holding the boot
//! count and the session a host asked for. A host's start request resets the board into the
//! new session, so each session's map begins from a fresh boot; a reset nobody asked for (the
//! watchdog, a brown-out, a debugger) boots into no session, and the host, which sees the boot
//! change in the next frame, knows the map it was getting is gone.

use core::mem::MaybeUninit;
use core::ptr::{addr_of_mut, read_volatile, write_volatile};

/// Marks the words as written by this firmware rather than left over from power-up.
const MAGIC: u32 = 0x4D45_4D41;

/// `[magic, boot count, pending session, its first carry number, check]`.
#[unsafe(link_section = ".uninit.mema_retained")]
static mut RETAINED: MaybeUninit<[u32; 5]> = MaybeUninit::uninit();

fn check(boot: u32, session: u32, first: u32) -> u32 {
    (boot ^ session.rotate_left(13) ^ first.rotate_left(7) ^ MAGIC).wrapping_mul(0x9E37_79B1)
}

/// Writes the retained words.
fn store(boot: u32, session: u32, first: u32) {
    let words = [MAGIC, boot, session, first, check(boot, session, first)];
    // SAFETY: only this module touches the words, from the main thread, with volatile
    // accesses; every bit pattern is a u32.
    unsafe {
        let at = addr_of_mut!(RETAINED).cast::<u32>();
        for (i, v) in words.into_iter().enumerate() {
            write_volatile(at.add(i), v);
        }
    }
}

/// The retained words as they are.
fn load() -> [u32; 5] {
    // SAFETY: as in `store`.
    unsafe {
        let at = addr_of_mut!(RETAINED).cast::<u32>();
        [0, 1, 2, 3, 4].map(|i| read_volatile(at.add(i)))
    }
}

/// This boot's identifier (never 0), the session it was reset into (`0`: none) and that
/// session's first carry number. The session is taken: a later reset nobody asked for boots
/// into no session.
pub fn take_boot() -> (u32, u32, u32) {
    let [magic, boot, session, first, sum] = load();
    let valid = magic == MAGIC && sum == check(boot, session, first);
    // At power-up SRAM holds noise: the boot count starts from it, so two power-ups seldom
    // share an identifier; after a reset it counts on.
    let boot = if valid { boot } else { boot ^ sum }.wrapping_add(1).max(1);
    let (session, first) = if valid { (session, first) } else { (0, 0) };
    store(boot, 0, 0);
    (boot, session, first)
}

/// Resets the part into `session`, its carry frames numbered from `first`: the next boot
/// begins it.
pub fn reset_into(session: u32, first: u32) -> ! {
    let [_, boot, ..] = load();
    store(boot, session, first);
    cortex_m::peripheral::SCB::sys_reset()
}
