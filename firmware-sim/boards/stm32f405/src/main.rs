//! The firmware on an STM32F405: `mema_firmware_sim::firmware::Firmware` fed by USART1's receive
//! interrupt, the map sent back on USART1's transmitter.
//!
//! The interrupt takes each byte from the data register and pushes it into the line's ring
//! (`LINE`, single-producer single-consumer). The host sends the points stream in carry frames
//! (PROTOCOL.md, "Host to device"): the main loop's [`Carrier`] passes on the stream bytes of
//! each one taken in turn into the ring the firmware ticks from (`MAP`), so the firmware maps
//! the host's stream whole and in order whatever the line did, and answers the host's requests.
//! The loop ticks while there is work, sends what the downlink has due (entities as they
//! freeze, progress with the carry frame expected next: "Device to host"), and sleeps (`wfi`)
//! while there is nothing to do. When the sender's end-of-stream frame has been mapped, the map
//! is finished with the host's seed, its remaining entities and end frame go out, and the
//! device goes on answering requests. No semihosting: this image talks only through the USART.
//! The entity model is shells, the host's default, or the paper's with the `paper` feature.
//!
//! Clocks: the PLL is set for 168 MHz from the 16 MHz internal oscillator, waiting a bounded
//! time for it to lock; where it does not (QEMU's `netduinoplus2` models no RCC and reads it as
//! 0), the part runs on the internal oscillator, and the baud rate divisor follows the clock it
//! actually has.
#![no_std]
#![no_main]

mod clocks;
// The 64 KiB image's painted stack, shared as a file: both images put the stack at the top of
// RAM above their statics.
#[path = "../../../image/src/stack.rs"]
mod stack;
// And its SysTick clock and calibration.
#[path = "../../../image/src/systick.rs"]
mod systick;
mod timing;
mod usart;

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_rt::entry;
use mema_core::link::downlink::DownFrame;
use mema_core::geometry::Entity;
use mema_core::query::brute_force;
use mema_core::stream::StreamModel;
use mema_firmware_sim::firmware::{
    BOARD_FROZEN, BOARD_WORKING, Carrier, Firmware, IMAGE_BUCKETS, IMAGE_REACH, RX_CAPACITY,
    Request, Ring, SHELLS, model_params,
};
use panic_never as _;
use static_cell::StaticCell;
use stm32f4::stm32f405::{self as pac, interrupt};

/// The board's layout, K = 2,048 as 150 working clusters and 1,898 frozen entities: the
/// board's map is `mema replay -k 2048 --working 150`'s.
const K: usize = BOARD_WORKING;
const G: usize = IMAGE_BUCKETS;
const F: usize = BOARD_FROZEN;
const SEED: u64 = 0;
/// The link's rate: 921,600 baud, 92 KB/s, as a companion computer's UART runs.
const BAUD: u32 = 921_600;

/// The line's ring: the interrupt pushes, the main loop's carrier consumes.
static LINE: Ring<RX_CAPACITY> = Ring::new();
/// The points stream taken from the carry frames: the carrier pushes, the firmware's ticks
/// consume.
static MAP: Ring<RX_CAPACITY> = Ring::new();
/// Bytes the ring had no room for, and bytes the USART lost before the interrupt read them.
static RING_OVERRUNS: AtomicU32 = AtomicU32::new(0);
static LINE_OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Delimiters received: a frame can only be whole after one, so the main loop ticks then
/// (and while mapping is under way) rather than at every byte.
static DELIMITERS: AtomicU32 = AtomicU32::new(0);

type BoardFirmware = Firmware<K, G, F, &'static Ring<RX_CAPACITY>>;
static FIRMWARE: StaticCell<BoardFirmware> = StaticCell::new();
/// The finished map's entities, for the host's queries: scanned whole (28 KB at K = 700; the
/// core's index over them would take 109 KB beside the mapper's 60).
static QUERY_MAP: StaticCell<[Entity; K + F]> = StaticCell::new();
/// How far a ray is followed, metres (the host's `RAY_REACH`).
const RAY_REACH: f64 = 1_000.0;

/// What the finished device answers from: its timing frame and its map's entities.
struct Finished<'a> {
    timing: DownFrame,
    entities: &'a [Entity],
}

/// Builds the state in its static (out of line, so it is built in place, not on the stack).
#[inline(never)]
fn boot(
    slot: &'static mut core::mem::MaybeUninit<BoardFirmware>,
    model: StreamModel,
) -> &'static mut BoardFirmware {
    slot.write(Firmware::with_ring(
        model_params(SEED, K, F, model),
        IMAGE_REACH,
        &MAP,
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
            if LINE.push(&[byte]) == 0 {
                RING_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            }
        }
        usart::Received::Overrun(byte) => {
            LINE_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            if byte == 0 {
                DELIMITERS.fetch_add(1, Ordering::Relaxed);
            }
            if LINE.push(&[byte]) == 0 {
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
    let calibration = systick::start(&mut cp.SYST);
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
    // SAFETY: the interrupt's handler only pushes into `LINE`, which is built for a producer in
    // an interrupt; nothing else it touches is shared.
    unsafe {
        // Below SysTick's 0, so the timer's wraps are counted while the handler is timed.
        cp.NVIC.set_priority(pac::Interrupt::USART1, 0x10);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1);
    }
    stack::paint();
    let mut work = timing::Work::default();
    let mut carrier = Carrier::new();
    let mut delimiters = 0;
    loop {
        let now = DELIMITERS.load(Ordering::Relaxed);
        if now != delimiters || firmware.mapping() || carrier.holding() {
            delimiters = now;
            // Until a pass neither maps nor finishes a frame nor holds carried bytes: the rings
            // then hold no whole frame (a tick decodes all it can), and the bytes of the next
            // one are left to arrive, rather than ticked through a byte at a time as they come.
            loop {
                work.other(|| carrier.pump(&LINE, &MAP, |r| answer(firmware, r, None)));
                let mut finished = false;
                work.tick(|| firmware.tick(|_| finished = true));
                if !(finished || firmware.mapping() || carrier.holding()) {
                    break;
                }
            }
            work.other(|| {
                firmware.send_frozen(usart::send);
                if let Some(report) = carrier.report_due(&LINE) {
                    firmware.send_progress(report, usart::send);
                }
            });
        }
        if firmware.stats().end_of_stream {
            break;
        }
        sleep_unless(|| DELIMITERS.load(Ordering::Relaxed) != delimiters || firmware.mapping());
    }
    firmware.finish();
    carrier.close();
    // What the stream cost, then the rest of the map entity by entity: the device holds no
    // copy of the file.
    let timing = DownFrame::Timing(work.report(calibration, stack::high_water()));
    firmware.send_frame(&timing, usart::send);
    let _ = firmware.send_end(usart::send);
    let entities = match QUERY_MAP.try_uninit() {
        Some(slot) => {
            let base = slot.as_mut_ptr().cast::<Entity>();
            let mut n = 0;
            for (i, e) in firmware.mapper().entities().take(K + F).enumerate() {
                // SAFETY: i < K + F, inside the array, and each entity is written before the
                // slice below reads it; written in place, so no 28 KB temporary on the stack.
                unsafe { base.add(i).write(e.entity) };
                n = i + 1;
            }
            // SAFETY: the first n entities were written above.
            unsafe { core::slice::from_raw_parts(base, n) }
        }
        None => &[],
    };
    let finished = Finished { timing, entities };
    // Then the host's requests, for as long as it asks.
    loop {
        // After a delimiter only: every byte's interrupt wakes the loop, and a pass over part
        // of a frame would send a progress frame for each byte.
        let now = DELIMITERS.load(Ordering::Relaxed);
        if now != delimiters {
            delimiters = now;
            carrier.pump(&LINE, &MAP, |r| answer(firmware, r, Some(&finished)));
            if let Some(report) = carrier.report_due(&LINE) {
                firmware.send_progress(report, usart::send);
            }
        }
        sleep_unless(|| DELIMITERS.load(Ordering::Relaxed) != delimiters);
    }
}

/// Answers a request of the host's: entities again, or once the map is finished the timing
/// and end frames again, or a query of the map (the core's no_std queries, timed).
fn answer(firmware: &mut BoardFirmware, request: Request, finished: Option<&Finished>) {
    match (request, finished) {
        (Request::Resend { first, count }, _) => firmware.resend(first, count, usart::send),
        (Request::ResendEnd, Some(f)) => {
            firmware.send_frame(&f.timing, usart::send);
            let _ = firmware.send_end_again(usart::send);
        }
        (
            Request::Query {
                number,
                ray,
                point,
                direction,
            },
            Some(f),
        ) => {
            let (t0, i0) = (systick::now(), timing::interrupt_ticks());
            let p = point.map(f64::from);
            let (entity, value) = if ray {
                brute_force::ray_cast(f.entities, p, direction.map(f64::from), RAY_REACH)
                    .map_or((u32::MAX, f64::INFINITY), |h| (h.entity as u32, h.t))
            } else {
                brute_force::nearest(f.entities, p).map_or((u32::MAX, f64::INFINITY), |n| {
                    (n.entity as u32, n.signed_distance)
                })
            };
            let ticks = (systick::now() - t0).saturating_sub(timing::interrupt_ticks() - i0);
            let frame = DownFrame::Answer {
                query: number,
                ray,
                entity,
                value,
                ticks: ticks.min(u64::from(u32::MAX)) as u32,
            };
            firmware.send_frame(&frame, usart::send);
        }
        // Not finished yet: the end goes out when it is, and queries wait for the map.
        (Request::ResendEnd | Request::Query { .. }, None) => {}
    }
}

/// Sleeps until an interrupt, unless `awake` says there is work: with interrupts masked, one
/// that comes after the look still wakes `wfi`, and runs once unmasked.
fn sleep_unless(awake: impl Fn() -> bool) {
    cortex_m::interrupt::free(|_| {
        if !awake() {
            cortex_m::asm::wfi();
        }
    });
}
