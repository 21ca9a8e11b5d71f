//! The firmware on an STM32F405: `mema_firmware_sim::firmware::Firmware` fed by USART1's receive
//! interrupt, the map sent back on USART1's transmitter.
//!
//! The interrupt takes each byte from the data register and pushes it into the ring the
//! firmware ticks from (`RX`, single-producer single-consumer); the main loop ticks while there
//! is work, sends what the downlink has due (entities as they freeze, progress as the ring
//! empties: PROTOCOL.md, "Device to host"), and sleeps (`wfi`) while there is nothing to do.
//! When the sender's end-of-stream frame has been mapped, the map is finished with the host's
//! seed and its remaining entities and end frame go out. No semihosting: this image talks only
//! through the USART. The entity model is shells, the host's default, or the paper's with the
//! `paper` feature.
//!
//! Clocks: the PLL is set for 168 MHz from the 16 MHz internal oscillator, waiting a bounded
//! time for it to lock; where it does not (QEMU's `netduinoplus2` models no RCC and reads it as
//! 0), the part runs on the internal oscillator, and the baud rate divisor follows the clock it
//! actually has.
#![no_std]
#![no_main]

mod clocks;
mod timing;
mod usart;

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_rt::entry;
use mema_core::downlink::DownFrame;
use mema_core::stream::StreamModel;
use mema_firmware_sim::firmware::{
    Firmware, IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_REACH, IMAGE_WORKING, RX_CAPACITY, Ring, SHELLS,
    model_params,
};
use panic_never as _;
use static_cell::StaticCell;
use stm32f4::stm32f405::{self as pac, interrupt};

/// The layout of today's image (K = 400 as 150 working clusters and 250 frozen entities), so
/// the board's map is `mema replay -k 400 --working 150`'s.
const K: usize = IMAGE_WORKING;
const G: usize = IMAGE_BUCKETS;
const F: usize = IMAGE_FROZEN;
const SEED: u64 = 0;
/// The link's rate: 921,600 baud, 92 KB/s, as a companion computer's UART runs.
const BAUD: u32 = 921_600;

/// The receive ring: the interrupt pushes, the main loop's ticks consume.
static RX: Ring<RX_CAPACITY> = Ring::new();
/// Bytes the ring had no room for, and bytes the USART lost before the interrupt read them.
static RING_OVERRUNS: AtomicU32 = AtomicU32::new(0);
static LINE_OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Delimiters received: a frame can only be whole after one, so the main loop ticks then
/// (and while mapping is under way) rather than at every byte.
static DELIMITERS: AtomicU32 = AtomicU32::new(0);

type BoardFirmware = Firmware<K, G, F, &'static Ring<RX_CAPACITY>>;
static FIRMWARE: StaticCell<BoardFirmware> = StaticCell::new();

/// Builds the state in its static (out of line, so it is built in place, not on the stack).
#[inline(never)]
fn boot(
    slot: &'static mut core::mem::MaybeUninit<BoardFirmware>,
    model: StreamModel,
) -> &'static mut BoardFirmware {
    slot.write(Firmware::with_ring(
        model_params(SEED, K, F, model),
        IMAGE_REACH,
        &RX,
    ))
}

#[interrupt]
fn USART1() {
    let _timed = timing::InInterrupt::start();
    match usart::receive() {
        usart::Received::Byte(byte) => {
            if byte == 0 {
                DELIMITERS.fetch_add(1, Ordering::Relaxed);
            }
            if RX.push(&[byte]) == 0 {
                RING_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            }
        }
        usart::Received::Overrun(byte) => {
            LINE_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            if byte == 0 {
                DELIMITERS.fetch_add(1, Ordering::Relaxed);
            }
            if RX.push(&[byte]) == 0 {
                RING_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            }
        }
        usart::Received::Nothing => {}
    }
}

#[entry]
fn main() -> ! {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        // Taken twice: nothing to run on.
        loop {
            cortex_m::asm::wfi();
        }
    };
    let clocks = clocks::setup(&dp.RCC, &dp.FLASH);
    let calibration = timing::start(&mut cp.SYST);
    usart::setup(&dp.RCC, &dp.GPIOA, dp.USART1, clocks.pclk2, BAUD);
    let model = if cfg!(feature = "paper") {
        StreamModel::Paper
    } else {
        SHELLS
    };
    let Some(slot) = FIRMWARE.try_uninit() else {
        loop {
            cortex_m::asm::wfi();
        }
    };
    let firmware = boot(slot, model);
    // SAFETY: the interrupt's handler only pushes into `RX`, which is built for a producer in
    // an interrupt; nothing else it touches is shared.
    unsafe {
        // Below SysTick's 0, so the timer's wraps are counted while the handler is timed.
        cp.NVIC.set_priority(pac::Interrupt::USART1, 0x10);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1);
    }
    let mut work = timing::Work::default();
    let mut delimiters = 0;
    loop {
        let now = DELIMITERS.load(Ordering::Relaxed);
        if now != delimiters || firmware.mapping() {
            delimiters = now;
            // Until a tick neither maps nor finishes a frame: the ring then holds no whole
            // frame (a tick decodes all it can), and the bytes of the next one are left to
            // arrive, rather than ticked through a byte at a time as they come.
            let mut more = true;
            while more {
                let mut finished = false;
                work.tick(|| firmware.tick(|_| finished = true));
                more = finished || firmware.mapping();
            }
            work.other(|| firmware.send_downlink(usart::send));
        }
        if firmware.stats().end_of_stream {
            break;
        }
        // Sleep until a delimiter comes, without missing one that came since it was looked
        // at: with interrupts masked, a pending one still wakes `wfi`, and runs once unmasked.
        cortex_m::interrupt::free(|_| {
            if DELIMITERS.load(Ordering::Relaxed) == delimiters && !firmware.mapping() {
                cortex_m::asm::wfi();
            }
        });
    }
    firmware.finish();
    // What the stream cost, then the rest of the map entity by entity: the device holds no
    // copy of the file.
    firmware.send_frame(&DownFrame::Timing(work.report(calibration)), usart::send);
    let _ = firmware.send_end(usart::send);
    usart::flush();
    loop {
        cortex_m::asm::wfi();
    }
}
