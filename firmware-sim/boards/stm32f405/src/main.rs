//! The firmware on an STM32F405: `mema_firmware::Firmware` fed by USART1's receive
//! interrupt, the map sent back on USART1's transmitter to a host, or on USART2's to a
//! listener when a sensor is wired to USART1.
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
//! device goes on answering requests. No semihosting: this image talks only through the USARTs.
//!
//! A sensor wired to USART1 sends its points and pose frames as they are (PROTOCOL.md), no
//! carry frames: booted in no session, the device passes USART1's bytes to the firmware as
//! they come, watching them for a host's start request until the firmware takes a sensor's
//! frame, and sends the map on USART2, whose receive side brings a listener's requests
//! (`mema device --listen`; `mema_firmware::device::Feed`). A sensor cannot be told to wait:
//! when the line's ring is full the USART1 interrupt leaves the byte in the data register and
//! masks itself until the main loop has made room. Under QEMU, which hands over the next byte
//! only once the register is read, that holds the line as flow control would; on silicon the
//! bytes that come meanwhile are lost and counted as the USART's overruns.
//! The entity model is shells, the host's default, or the paper's with the `paper` feature.
//!
//! Clocks: the PLL is set for 168 MHz from the 16 MHz internal oscillator, waiting a bounded
//! time for it to lock; where it does not (QEMU's `netduinoplus2` models no RCC and reads it as
//! 0), the part runs on the internal oscillator, and the baud rate divisor follows the clock it
//! actually has.
#![no_std]
#![no_main]

mod clocks;
mod retained;
mod timing;
mod usart;
mod watchdog;

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m_rt::entry;
use mema_core::link::downlink::{DeviceLayout, DeviceTiming};
use mema_core::link::frame::Address;
use mema_core::stream::{Carver, StreamModel};
use mema_firmware::cortex_m::{stack, systick};
use mema_firmware::device::{Boot, Clock, Device, LISTENER_RING, Out, Poll};
use mema_firmware::{
    BOARD_CARVE_EVERY, BOARD_CARVE_IMAGE, BOARD_CARVE_PIXELS, BOARD_FROZEN, BOARD_WORKING,
    Firmware, IMAGE_BUCKETS, IMAGE_REACH, RX_CAPACITY, Ring, SHELLS, model_params,
};
use panic_never as _;
use static_cell::StaticCell;
use stm32f4::stm32f405::{self as pac, interrupt};

/// The board's layout, K = 700 as 150 working clusters and 550 frozen entities, carving on a
/// 124 x 512 range image every second scan: the board's map is
/// `mema replay -k 700 --working 150 --carve 124x512 --carve-every 2`'s.
const K: usize = BOARD_WORKING;
const G: usize = IMAGE_BUCKETS;
const F: usize = BOARD_FROZEN;
const SEED: u64 = 0;
/// The link's rate: 921,600 baud, 92 KB/s, as a companion computer's UART runs.
const BAUD: u32 = 921_600;

/// The line's ring: the interrupt pushes, the main loop's carrier consumes.
static LINE: Ring<RX_CAPACITY> = Ring::new();
/// USART1's interrupt is masked, its byte left in the data register: the line's ring was full.
static HELD: AtomicBool = AtomicBool::new(false);
/// USART2's receive ring: a listener's requests.
static LISTENER: Ring<LISTENER_RING> = Ring::new();
/// The points stream taken from the carry frames: the carrier pushes, the firmware's ticks
/// consume.
static MAP: Ring<RX_CAPACITY> = Ring::new();
/// Bytes the ring had no room for, and bytes the USART lost before the interrupt read them.
static RING_OVERRUNS: AtomicU32 = AtomicU32::new(0);
static LINE_OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Delimiters received: a frame can only be whole after one, so the main loop works then
/// (and while mapping is under way) rather than at every byte.
static DELIMITERS: AtomicU32 = AtomicU32::new(0);

type BoardCarver = Carver<BOARD_CARVE_PIXELS>;
type BoardFirmware = Firmware<K, G, F, &'static Ring<RX_CAPACITY>, &'static mut BoardCarver>;
static FIRMWARE: StaticCell<BoardFirmware> = StaticCell::new();
/// The carver, its range image filling the core-coupled RAM (`memory/*.x`: neither loaded nor
/// zeroed, so it is built at boot, once).
#[unsafe(link_section = ".ccmram")]
static mut CARVER: core::mem::MaybeUninit<BoardCarver> = core::mem::MaybeUninit::uninit();

/// Builds the state in its static (out of line, so it is built in place, not on the stack).
#[inline(never)]
fn boot(
    slot: &'static mut core::mem::MaybeUninit<BoardFirmware>,
    model: StreamModel,
) -> &'static mut BoardFirmware {
    slot.write(Firmware::carving(
        model_params(SEED, K, F, model),
        IMAGE_REACH,
        &MAP,
        carver(),
    ))
}

/// The carver, built in place in the core-coupled RAM. Called once, from `boot`.
#[inline(never)]
fn carver() -> &'static mut BoardCarver {
    // SAFETY: `boot` runs once a reset, before anything else refers to `CARVER`, and hands
    // the only reference to the firmware.
    let slot = unsafe { (&raw mut CARVER).as_mut() };
    let Some(slot) = slot else {
        // A static's address is never null.
        loop {
            cortex_m::asm::wfi();
        }
    };
    let carver = slot.write(Carver::empty());
    let [rows, columns] = BOARD_CARVE_IMAGE;
    carver.look(rows, columns);
    carver.sample(BOARD_CARVE_EVERY);
    carver
}

#[interrupt]
fn USART1() {
    let _timed = timing::InInterrupt::start();
    if LINE.len() == RX_CAPACITY {
        // No room: the byte waits in the data register until the main loop has made room.
        cortex_m::peripheral::NVIC::mask(pac::Interrupt::USART1);
        HELD.store(true, Ordering::Release);
        return;
    }
    take(usart::receive(usart::Port::Usart1), &LINE);
}

#[interrupt]
fn USART2() {
    let _timed = timing::InInterrupt::start();
    take(usart::receive(usart::Port::Usart2), &LISTENER);
}

/// A receive interrupt's byte into its ring, delimiters and overruns counted.
#[inline(always)]
fn take<const N: usize>(received: usart::Received, ring: &Ring<N>) {
    let byte = match received {
        usart::Received::Byte(byte) => byte,
        usart::Received::Overrun(byte) => {
            LINE_OVERRUNS.fetch_add(1, Ordering::Relaxed);
            byte
        }
        usart::Received::Nothing => return,
    };
    if byte == 0 {
        DELIMITERS.fetch_add(1, Ordering::Relaxed);
    }
    if !ring.push_byte(byte) {
        RING_OVERRUNS.fetch_add(1, Ordering::Relaxed);
    }
}

/// After a pass: USART1's interrupt unmasked once its ring has room again.
fn release_line() {
    if HELD.load(Ordering::Acquire) && LINE.len() < RX_CAPACITY {
        HELD.store(false, Ordering::Relaxed);
        // SAFETY: the handler it unmasks only pushes into `LINE`, as at boot.
        unsafe { cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART1) };
    }
}

/// The board's clock for the device's loop: SysTick, interrupts counted apart.
struct BoardClock {
    work: timing::Work,
    calibration: systick::Calibration,
}

impl Clock for BoardClock {
    fn tick(&mut self, work: impl FnOnce()) {
        self.work.tick(work)
    }

    fn other<T>(&mut self, work: impl FnOnce() -> T) -> T {
        self.work.note_interrupt_cycles();
        self.work.other(work)
    }

    fn query<T>(&mut self, work: impl FnOnce() -> T) -> (T, u32) {
        let (t0, i0) = (systick::now(), timing::interrupt_ticks());
        let out = work();
        let ticks = (systick::now() - t0).saturating_sub(timing::interrupt_ticks() - i0);
        (out, ticks.min(u64::from(u32::MAX)) as u32)
    }

    fn timing(&self) -> DeviceTiming {
        let overruns = (
            RING_OVERRUNS.load(Ordering::Relaxed),
            LINE_OVERRUNS.load(Ordering::Relaxed),
        );
        self.work
            .report(self.calibration, stack::high_water(), overruns)
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
    // Which boot this is, and the session a host asked for before the reset that began it.
    let (boot_id, session, first_carry) = retained::take_boot();
    let clocks = clocks::setup(&dp.RCC, &dp.FLASH);
    let calibration = systick::start(&mut cp.SYST);
    // Cycles as silicon counts them, beside the ticks (QEMU models no DWT: the count stays 0).
    timing::start_cycles(&mut cp.DCB, &mut cp.DWT);
    usart::setup(&dp.RCC, &dp.GPIOA, clocks, BAUD);
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
    // SAFETY: the interrupts' handlers only push into `LINE` and `LISTENER`, which are built
    // for a producer in an interrupt; nothing else they touch is shared.
    unsafe {
        // Below SysTick's 0, so the timer's wraps are counted while a handler is timed.
        for usart in [pac::Interrupt::USART1, pac::Interrupt::USART2] {
            cp.NVIC.set_priority(usart, 0x10);
            cortex_m::peripheral::NVIC::unmask(usart);
        }
    }
    stack::paint();
    watchdog::start(&dp.IWDG);
    let layout = DeviceLayout {
        capacity: (K + F) as u32,
        working: K as u32,
        model: u8::from(!cfg!(feature = "paper")),
    };
    let boot = Boot {
        address: Address {
            session,
            boot: boot_id,
        },
        first_carry,
        first_sequence: 0,
    };
    let mut device = Device::new(firmware, (&LINE, &MAP), boot, layout).wired(&LISTENER);
    let mut clock = BoardClock {
        work: timing::Work::default(),
        calibration,
    };
    loop {
        watchdog::feed();
        let poll = device.poll(
            DELIMITERS.load(Ordering::Relaxed),
            &mut clock,
            &mut |out, bytes| match out {
                Out::Host => usart::send(usart::Port::Usart1, bytes),
                Out::Listener => usart::send(usart::Port::Usart2, bytes),
            },
        );
        release_line();
        match poll {
            Poll::Idle => sleep_unless(|| device.awake(DELIMITERS.load(Ordering::Relaxed))),
            Poll::Reset { session, first } => {
                // A new session's map starts from a fresh boot: nothing of the last in RAM.
                usart::flush(usart::Port::Usart1);
                retained::reset_into(session, first)
            }
        }
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
