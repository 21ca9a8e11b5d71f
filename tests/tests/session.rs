//! `mema device`'s session (issues 22, 30) against the board's own loop run in a thread
//! (`firmware::device::Device`: line ring, carrier, firmware ring, ticks, downlink, resets into
//! a new session), over an in-memory line that drops,
//! flips and duplicates bytes both ways (seeded, more often than the QEMU relay test can
//! afford): every seed ends with `mema replay`'s map byte for byte, the faults seen, sent and
//! asked again, and none hangs.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::thread;
use std::time::Duration;

use mema::link::device::MapFrames;
use mema::link::session::{SILENCE, SessionLimits, send_and_receive};
use mema_core::link::downlink::{DeviceLayout, RING_BYTES};
use mema_core::link::frame::Address;
use mema_firmware::device::{Boot, Device, NoClock, Out, Poll};
use mema_firmware::{
    BOARD_CARVE_EVERY, BOARD_CARVE_IMAGE, BOARD_CARVE_PIXELS, BOARD_FROZEN, Carving, Firmware,
    IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_REACH, IMAGE_WORKING, RX_CAPACITY, Ring, SHELLS,
    model_params,
};

use crate::device::capture_and_replay;
use crate::faults::Rng;
use crate::util::{Dir, MemaCommand};
use mema_firmware_sim::fault::LineFaults;

/// Bytes through a line that drops, flips or duplicates one in `one_in` (0: none): the one
/// fault injector of the link's tests.
struct Line(LineFaults);

impl Line {
    fn carry(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(bytes.len() + 8);
        self.0.carry(bytes, |b| out.push(b));
        out
    }
}

/// The host's end: writes go through the faulty line to the device, reads wait a little for
/// the device's bytes, as a serial port with a timeout does.
struct Port {
    to_device: Sender<Vec<u8>>,
    from_device: Receiver<Vec<u8>>,
    held: VecDeque<u8>,
    line: Line,
}

impl Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.held.is_empty() {
            match self.from_device.recv_timeout(Duration::from_millis(20)) {
                Ok(bytes) => self.held.extend(bytes),
                Err(RecvTimeoutError::Timeout) => return Err(ErrorKind::TimedOut.into()),
                Err(RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
        let n = buf.len().min(self.held.len());
        for (slot, b) in buf.iter_mut().zip(self.held.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

impl Write for Port {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let bytes = self.line.carry(buf);
        self.to_device
            .send(bytes)
            .map_err(|_| std::io::Error::from(ErrorKind::BrokenPipe))?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The device: the board's main loop ([`Device`], the function the board calls), bytes from
/// `input`, frames out through `line` to `output`, until the host hangs up; a start request
/// for a new session "resets" it (a fresh firmware in a new boot), as the board resets. Returns
/// the faults its line made.
fn run_device(
    input: Receiver<Vec<u8>>,
    output: Sender<Vec<u8>>,
    line: Line,
    near_wrap: bool,
) -> u64 {
    run_carving_device::<IMAGE_FROZEN, ()>(input, output, line, near_wrap, || ())
}

/// [`run_device`] with `F` frozen entities, carving with what `carving` gives at each boot.
fn run_carving_device<const F: usize, C: Carving>(
    input: Receiver<Vec<u8>>,
    output: Sender<Vec<u8>>,
    mut line: Line,
    near_wrap: bool,
    carving: impl Fn() -> C,
) -> u64 {
    let (mut boot, mut session, mut first_carry) = (1u32, 0u32, 0u32);
    // Every counter of the device just before its wrap, or from 0 as a board boots.
    let (ring_start, first_sequence, first_delimiters) = if near_wrap {
        (usize::MAX - 1_500, u32::MAX - 20, u32::MAX - 40)
    } else {
        (0, 0, 0)
    };
    let layout = DeviceLayout {
        capacity: (IMAGE_WORKING + F) as u32,
        working: IMAGE_WORKING as u32,
        model: 1,
    };
    loop {
        let (line_ring, map_ring) = (
            Ring::<RX_CAPACITY>::counting_from(ring_start),
            Ring::<RX_CAPACITY>::counting_from(ring_start),
        );
        let params = model_params(0, IMAGE_WORKING, F, SHELLS);
        let mut firmware: Box<Firmware<IMAGE_WORKING, IMAGE_BUCKETS, F, _, C>> =
            Box::new(Firmware::carving(params, IMAGE_REACH, &map_ring, carving()));
        let start = Boot {
            address: Address { session, boot },
            first_carry,
            first_sequence,
        };
        let mut device = Device::new(&mut firmware, (&line_ring, &map_ring), start, layout);
        let mut delimiters = first_delimiters;
        let mut sent = Vec::new();
        let reset = loop {
            match input.recv_timeout(Duration::from_millis(5)) {
                // Past the ring's room the bytes are lost, as a UART overrun loses them.
                Ok(bytes) => {
                    let zeros = bytes.iter().filter(|&&b| b == 0).count() as u32;
                    delimiters = delimiters.wrapping_add(zeros);
                    let _ = line_ring.push(&bytes);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return line.0.faults,
            }
            let mut poll = Poll::Idle;
            while poll == Poll::Idle && device.awake(delimiters) {
                poll = device.poll(delimiters, &mut NoClock, &mut |_: Out, b: &[u8]| {
                    sent.extend_from_slice(b)
                });
            }
            if !sent.is_empty() && output.send(line.carry(&sent)).is_err() {
                return line.0.faults;
            }
            sent.clear();
            if let Poll::Reset { session, first } = poll {
                break (session, first);
            }
        };
        (session, first_carry) = reset;
        boot += 1;
    }
}

#[test]
fn sessions_through_faulty_lines_end_with_the_replay_map() {
    let dir = Dir::new("session-faults");
    let layout = (IMAGE_WORKING + IMAGE_FROZEN, IMAGE_WORKING);
    let (_, stream, replayed) = capture_and_replay(&dir, "car6.pcd", layout, "shells");
    let (mut resent, mut asked_again) = (0, 0);
    // Seed 0: a clean line, and nothing to send or ask again. Seeds 6 and 7: every counter
    // on both sides (the rings', the delimiters', the downlink's sequence, the carry numbers)
    // starts just before its wrap and crosses it, through a faulty line and a clean one.
    let cases = (0..6u64).map(|s| (s, false)).chain([(6, true), (7, true)]);
    for (seed, near_wrap) in cases {
        let one_in = if seed == 0 || seed == 7 { 0 } else { 1_500 };
        let (to_device, device_in) = channel();
        let (device_out, from_device) = channel();
        let down = Line(LineFaults::new(seed.wrapping_mul(2) + 1, one_in));
        let device = thread::spawn(move || run_device(device_in, device_out, down, near_wrap));
        let mut port = Port {
            to_device,
            from_device,
            held: VecDeque::new(),
            line: Line(LineFaults::new(seed.wrapping_mul(2), one_in)),
        };
        let mut frames = MapFrames::default();
        let limits = SessionLimits {
            window: RING_BYTES,
            silence: SILENCE,
            first_carry: if near_wrap { u32::MAX - 5 } else { 0 },
        };
        let map = send_and_receive(&mut port, &stream, limits, &mut frames, |_| {});
        let up_faults = port.line.0.faults;
        drop(port);
        let down_faults = device.join().expect("the device thread");
        let map = map.unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let c = &frames.counts;
        eprintln!("seed {seed}: {up_faults} faults up, {down_faults} down: {c:?}");
        assert!(map == replayed, "seed {seed}: not replay's map: {c:?}");
        if one_in == 0 {
            // (Frames may still be sent again if the machine stalls the device for a second.)
            assert_eq!(
                (c.device_refused, c.refused, c.lost, c.asked_again),
                (0, 0, 0, 0)
            );
            continue;
        }
        assert!(up_faults > 0 && down_faults > 0, "seed {seed}");
        // Faults on the way up make the device refuse frames and the host send them again;
        // those on the way down cost frames the host notices.
        assert!(c.device_refused > 0 && c.resent > 0, "seed {seed}: {c:?}");
        assert!(c.refused + c.lost > 0, "seed {seed}: {c:?}");
        resent += c.resent;
        asked_again += c.asked_again + c.ends_asked;
    }
    assert!(
        resent > 0 && asked_again > 0,
        "{resent} resent, {asked_again} asked again"
    );
}

/// A device that never answers, and one that answers only noise: `mema device` gives up after
/// its idle timeout with one line and exit 1, and writes no map.
#[test]
fn a_silent_or_babbling_device_ends_the_session_without_a_map() {
    let dir = Dir::new("session-dead");
    let (capture, _, _) = capture_and_replay(&dir, "car6.pcd", (400, 150), "shells");
    for babble in [false, true] {
        let pair = crate::stream::PtyPair::new(&dir);
        let far = pair.a.clone();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stopping = stop.clone();
        // The far end: read and drop what the host sends; answer noise, or nothing.
        let device = thread::spawn(move || {
            let Ok(mut port) = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(&far)
            else {
                return;
            };
            let mut rng = Rng(0x2545_F491_4F6C_DD1D);
            while !stopping.load(std::sync::atomic::Ordering::Relaxed) {
                if babble {
                    let noise: Vec<u8> = (0..64).map(|_| rng.next() as u8).collect();
                    if port.write_all(&noise).is_err() {
                        return;
                    }
                }
                thread::sleep(Duration::from_millis(5));
            }
        });
        let out = dir.join(&format!("dead-{babble}.mema"));
        MemaCommand::new(&dir)
            .args(["device", "--port"])
            .arg(&pair.b)
            .arg(&capture)
            .arg("-o")
            .arg(&out)
            .args(["--idle-timeout", "2", "--json"])
            .run()
            // Noise is what a line at the wrong baud rate brings: said as such.
            .assert_error(
                1,
                if babble {
                    "no valid frame in 2 s"
                } else {
                    "said nothing new for 2 s"
                },
            );
        assert!(!out.exists(), "babble {babble}: a map was written");
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        drop(pair);
        let _ = device.join();
    }
}

/// The board's layout carving (issue 29): someone walks across the robot's line of sight, each
/// stop's scan sent in four pieces after the same pose, so the origin settles (16 poses) at the
/// fourth stop and frozen entities go down the link as they freeze; later scans carve some of
/// them. The device, its downlink running only between passes as the board's does, retracts
/// them and sends what took their slots (an entity frozen into a vacated slot included: once
/// the host kept the slot's old entity, and the end's check, then the CRC of the whole file,
/// always the CRC-32 residue, passed it). The host's map is `mema replay`'s.
#[test]
fn a_carving_device_keeps_the_hosts_copy_through_retractions() {
    type BoardCarver = mema_core::stream::Carver<BOARD_CARVE_PIXELS>;
    let dir = Dir::new("session-carving");
    let stream = crate::board_carving::walking_in_pieces();
    let capture = dir.write("walking.bin", &stream);
    let layout = (IMAGE_WORKING + BOARD_FROZEN, IMAGE_WORKING);
    // The board's layout: `replay` carves as the board does.
    let replayed = crate::device::replay(&dir, &capture, layout, "shells");
    let (to_device, device_in) = channel();
    let (device_out, from_device) = channel();
    let carving = || {
        let mut carver = Box::new(BoardCarver::empty());
        let [rows, columns] = BOARD_CARVE_IMAGE;
        assert!(carver.look(rows, columns));
        carver.sample(BOARD_CARVE_EVERY);
        Box::leak(carver)
    };
    let down = Line(LineFaults::new(1, 0));
    let device = thread::spawn(move || {
        run_carving_device::<BOARD_FROZEN, _>(device_in, device_out, down, false, carving)
    });
    let mut port = Port {
        to_device,
        from_device,
        held: VecDeque::new(),
        line: Line(LineFaults::new(0, 0)),
    };
    let mut frames = MapFrames::default();
    let limits = SessionLimits {
        window: RING_BYTES,
        silence: SILENCE,
        first_carry: 0,
    };
    let map = send_and_receive(&mut port, &stream, limits, &mut frames, |_| {});
    drop(port);
    device.join().expect("the device thread");
    let map = map.unwrap_or_else(|e| panic!("{e}"));
    let c = &frames.counts;
    assert!(c.retracted > 0, "nothing was retracted: {c:?}");
    assert!(map == replayed, "not replay's map: {c:?}");
}
