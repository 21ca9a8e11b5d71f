//! The firmware image: `mema_firmware::Firmware` on a Cortex-M4F.
//!
//! Under `qemu-system-arm -machine mps2-an386 -semihosting`, it reads `capture.bin` from QEMU's
//! working directory through semihosting, in chunks of 1..=256 bytes as a UART interrupt would
//! hand them over, ticks the firmware after each chunk, finishes the map with the same seed as
//! the host, and writes the map's bytes to `map.mema` beside the capture. The entity model is
//! shells, the host's default, unless a file `model.txt` there says `paper` (a device would
//! take it from its configuration the same way: one image, either model). It then prints one
//! line of measurements (`key=value`), which `mema-firmware-sim budget` reads:
//! - `ingest_ticks` / `finish_ticks`: SysTick counts over the ingest loop and over `finish`.
//!   Under `-icount shift=0` QEMU's clock advances one nanosecond per instruction, so with the
//!   calibration loop (`calib_insns` instructions took `calib_ticks`) they convert to
//!   instructions executed;
//! - `stack_tick` / `stack_finish`: the stack's high-water mark in bytes during the ingest loop
//!   and during `finish`, from a painted stack.
//!
//! No formatting machinery (`core::fmt`) is linked, and `panic-never` makes any surviving panic
//! path a link error: that the image links at all shows the core's entry points it calls are
//! panic-free in this release build.
#![no_std]
#![no_main]

mod io;

use cortex_m_rt::entry;
use mema_core::stream::StreamModel;
use mema_firmware::cortex_m::stack;
use mema_firmware::cortex_m::systick::{self, now};
use mema_firmware::source::{ByteSource, Delivery};
use mema_firmware::{
    Firmware, IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_REACH, IMAGE_WORKING, SHELLS, model_params,
};
use panic_never as _;
use static_cell::StaticCell;

/// Working clusters, centre-hash buckets and frozen entities of the image: K = 400 ellipsoids
/// (the host tests map with `-k 400 --working 150`).
const K: usize = IMAGE_WORKING;
const G: usize = IMAGE_BUCKETS;
const F: usize = IMAGE_FROZEN;
const SEED: u64 = 0;

/// The application state lives in .bss, built in place at boot (never on the stack).
static FIRMWARE: StaticCell<Firmware<K, G, F>> = StaticCell::new();

/// Builds the state in its static. Kept out of line so the compiler constructs the value in the
/// slot itself rather than in a stack temporary (which would need as much stack as the state).
#[inline(never)]
fn boot(
    slot: &'static mut core::mem::MaybeUninit<Firmware<K, G, F>>,
    model: StreamModel,
) -> &'static mut Firmware<K, G, F> {
    slot.write(Firmware::with_reach(
        model_params(SEED, K, F, model),
        IMAGE_REACH,
    ))
}

/// SysTick times of one kind of tick.
#[derive(Default)]
struct TickTimes {
    max: u64,
    sum: u64,
    ticks: u64,
    points: u64,
}

/// The model `model.txt` asks for: the paper's if it begins with `paper`, else shells.
fn configured_model() -> StreamModel {
    let mut text = [0u8; 8];
    match io::read_file(b"model.txt\0", &mut text) {
        Some(n) if text.get(..n).is_some_and(|t| t.starts_with(b"paper")) => StreamModel::Paper,
        _ => SHELLS,
    }
}

#[entry]
fn main() -> ! {
    stack::paint();
    let status = match run() {
        Ok(()) => cortex_m_semihosting::debug::EXIT_SUCCESS,
        Err(what) => {
            io::print(&[b"mema-image: error: ", what.as_bytes(), b"\n"]);
            cortex_m_semihosting::debug::EXIT_FAILURE
        }
    };
    cortex_m_semihosting::debug::exit(status);
    #[allow(clippy::empty_loop)]
    loop {}
}

fn run() -> Result<(), &'static str> {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        return Err("peripherals taken twice");
    };
    let calibration = systick::start(&mut core.SYST);
    let (calib_ticks, calib_insns) = (calibration.ticks, calibration.insns);

    // `try_init_with`, not `init_with`: a second initialisation is an error, not a panic.
    let model = configured_model();
    let firmware = boot(
        FIRMWARE.try_uninit().ok_or("FIRMWARE initialised twice")?,
        model,
    );
    let stack_boot = stack::high_water();
    stack::paint();
    let mut uart =
        io::SemihostingUart::open(b"capture.bin\0", SEED).ok_or("cannot open capture.bin")?;

    let mut chunk = [0u8; 256];
    // Ticks that only mapped points, ticks that also fitted (a freeze or a refit), ticks that
    // also ran a merge pass (at most one of those per tick) and ticks whose freeze scanned the
    // frozen store for pairs to coarsen: the longest, and the sums the per-point, per-fit,
    // per-merge-pass and per-scan prices come from.
    let (mut plain, mut unit, mut merge, mut scan) = (
        TickTimes::default(),
        TickTimes::default(),
        TickTimes::default(),
        TickTimes::default(),
    );
    let work = |s: &mema_core::stream::StreamStats| (s.frozen, s.merges, s.refits, s.scans);
    let t0 = now();
    loop {
        match uart.deliver(&mut chunk) {
            Ok(Delivery::Bytes(n)) => {
                firmware.on_receive(chunk.get(..n).unwrap_or(&[]));
                while firmware.busy() {
                    let before = work(firmware.mapper_stats());
                    let points = firmware.mapper_stats().points;
                    let t = now();
                    firmware.tick(|_| {});
                    let dt = now() - t;
                    let mapped = firmware.mapper_stats().points - points;
                    let after = work(firmware.mapper_stats());
                    let kind = if after == before {
                        &mut plain
                    } else if after.1 != before.1 {
                        &mut merge
                    } else if after.3 != before.3 {
                        &mut scan
                    } else {
                        &mut unit
                    };
                    kind.max = kind.max.max(dt);
                    kind.sum += dt;
                    kind.ticks += 1;
                    kind.points += mapped;
                }
                if firmware.stats().end_of_stream {
                    break;
                }
            }
            Ok(Delivery::End) | Ok(Delivery::Reset) => break,
            Err(e) => match e {},
        }
    }
    let ingest_ticks = now() - t0;
    let stack_tick = stack::high_water();

    stack::paint();
    let t0 = now();
    firmware.finish();
    // The map goes out as it is encoded, a piece at a time: 400 entities would be 10 KB of RAM.
    let mut encoded = Err("map not encoded");
    let written = io::write_file(b"map.mema\0", |sink| {
        encoded = firmware
            .send_map(|piece| sink(piece))
            .map_err(|_| "more than 2^32 - 1 entities");
    });
    let finish_ticks = now() - t0;
    let stack_finish = stack::high_water();
    let len = encoded?;
    if !written {
        return Err("cannot write map.mema");
    }
    let fw = firmware.stats();
    let mapper = firmware.mapper_stats();
    let decoder = firmware.decoder_stats();
    let fields: [(&[u8], u64); 35] = [
        (b"k", (K + F) as u64),
        (b"shells", u64::from(model != StreamModel::Paper)),
        (b"points", mapper.points),
        (b"frames", fw.frames),
        (b"rejected", decoder.rejected),
        (b"entities", firmware.mapper().entities().count() as u64),
        (b"frozen", firmware.mapper().frozen().len() as u64),
        (b"map_bytes", len as u64),
        (b"end_of_stream", u64::from(fw.end_of_stream)),
        (b"ingest_ticks", ingest_ticks),
        (b"finish_ticks", finish_ticks),
        (b"calib_ticks", calib_ticks),
        (b"calib_insns", calib_insns),
        (b"stack_boot", stack_boot as u64),
        (b"stack_tick", stack_tick as u64),
        (b"stack_finish", stack_finish as u64),
        (b"refits", mapper.refits),
        (b"bytes", decoder.bytes),
        (b"tick_plain_max_ticks", plain.max),
        (b"tick_plain_sum_ticks", plain.sum),
        (b"tick_plain_points", plain.points),
        (b"tick_unit_max_ticks", unit.max),
        (b"tick_unit_sum_ticks", unit.sum),
        (b"tick_unit_points", unit.points),
        (b"unit_ticks", unit.ticks),
        (b"tick_merge_max_ticks", merge.max),
        (b"tick_merge_sum_ticks", merge.sum),
        (b"tick_merge_points", merge.points),
        (b"merge_ticks", merge.ticks),
        (b"tick_scan_max_ticks", scan.max),
        (b"tick_scan_sum_ticks", scan.sum),
        (b"tick_scan_points", scan.points),
        (b"scan_ticks", scan.ticks),
        (b"ticks", fw.ticks),
        (b"tick_points_peak", fw.tick_points_peak as u64),
    ];
    io::print(&[b"mema-image:"]);
    for (key, value) in fields {
        let mut digits = [0u8; 20];
        io::print(&[b" ", key, b"=", io::decimal(value, &mut digits)]);
    }
    io::print(&[b"\n"]);
    Ok(())
}
