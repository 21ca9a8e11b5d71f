//! The map back over the link (issue 22): the firmware's downlink frames, taken by the host's
//! `MapFrames` in any pieces, rebuild `mema replay`'s map byte for byte; with bytes of the
//! downlink dropped, flipped or duplicated (seeded), the host never writes a wrong map: it
//! either has the device's map to the bit or says which entities it lacks.

use std::path::{Path, PathBuf};

use mema::link::device::{DeviceError, MapFrames};
use mema_core::link::downlink::{self, DeviceLayout, DownFrame, MAX_DOWN_FRAME_LEN, SessionStatus};
use mema_core::link::frame::Address;
use mema_core::link::framing;
use mema_core::stream::StreamModel;
use mema_firmware::{
    BOARD_CARVE_EVERY, BOARD_CARVE_IMAGE, BOARD_FROZEN, BOARD_WORKING, Firmware, IMAGE_BUCKETS,
    IMAGE_FROZEN, IMAGE_REACH, IMAGE_WORKING, SHELLS, model_params,
};

use crate::util::{Dir, MemaCommand, shared};
use mema_firmware_sim::fault::LineFaults;

type Image = Firmware<IMAGE_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN>;

/// The capture `mema scanner-sim` writes for `cloud` (its path and bytes; `demo`: the demo
/// drive, scanner-sim's default), and `mema replay`'s map of it at `k` ellipsoids, `working`
/// of them in working memory, in `model`.
pub(crate) fn capture_and_replay(
    dir: &Dir,
    cloud: &str,
    layout: (usize, usize),
    model: &str,
) -> (PathBuf, Vec<u8>, Vec<u8>) {
    let capture = dir.join(&format!("{cloud}.bin"));
    if !capture.exists() {
        let sim = MemaCommand::new(dir)
            .args(["scanner-sim", "--port"])
            .arg(&capture);
        let sim = if cloud == "demo" {
            sim
        } else {
            sim.arg(shared(cloud))
        };
        sim.run().assert_ok();
    }
    let map = replay(dir, &capture, layout, model);
    let bytes = std::fs::read(&capture).expect("capture");
    (capture, bytes, map)
}

/// `mema replay`'s map of `capture` at `k` ellipsoids, `working` of them in working memory, in
/// `model`; at the board's layout, carving as the board carves (its images, every other
/// return: `BOARD_CARVE_IMAGE`, `BOARD_CARVE_EVERY`), which the 64 KiB image has no room for.
pub(crate) fn replay(
    dir: &Dir,
    capture: &Path,
    (k, working): (usize, usize),
    model: &str,
) -> Vec<u8> {
    let name = capture
        .file_stem()
        .map_or("capture".into(), |s| s.to_string_lossy());
    let map = dir.join(&format!("{name}-{k}-{model}.mema"));
    let board = (k, working) == (BOARD_WORKING + BOARD_FROZEN, BOARD_WORKING);
    let [rows, columns] = BOARD_CARVE_IMAGE;
    let carve = [
        "--carve".to_string(),
        format!("{rows}x{columns}"),
        "--carve-every".to_string(),
        BOARD_CARVE_EVERY.to_string(),
    ];
    let (k, working) = (k.to_string(), working.to_string());
    MemaCommand::new(dir)
        .arg("replay")
        .arg(capture)
        .args(["-k", &k, "--working", &working, "--model", model, "-o"])
        .arg(&map)
        .args(carve.iter().filter(|_| board))
        .run()
        .assert_ok();
    std::fs::read(&map).expect("map")
}

/// The session these tests' device is in, and its boot.
const SESSION: Address = Address {
    session: 0x00C0_FFEE,
    boot: 1,
};

/// The image's layout (K = 400: 150 working, 250 frozen).
const IMAGE: (usize, usize) = (IMAGE_WORKING + IMAGE_FROZEN, IMAGE_WORKING);

/// The device's side, as the board's main loop runs it: bytes in, ticks, the downlink's frames
/// after each pass, the rest and the end after finishing. Returns everything it sent.
fn device_downlink(capture: &[u8], model: StreamModel) -> Vec<u8> {
    device_downlink_as(capture, model, SESSION)
}

/// [`device_downlink`] from a device in `address`'s boot and session.
fn device_downlink_as(capture: &[u8], model: StreamModel, address: Address) -> Vec<u8> {
    let params = model_params(0, IMAGE_WORKING, IMAGE_FROZEN, model);
    let mut firmware: Box<Image> = Box::new(Firmware::with_reach(params, IMAGE_REACH));
    firmware.set_link_address(address, 0);
    let mut sent = Vec::new();
    let started = DownFrame::Session {
        status: SessionStatus::Started,
        layout: DeviceLayout {
            capacity: (IMAGE_WORKING + IMAGE_FROZEN) as u32,
            working: IMAGE_WORKING as u32,
            model: 1,
        },
    };
    firmware.send_frame(&started, |bytes| sent.extend_from_slice(bytes));
    for chunk in capture.chunks(97) {
        firmware.on_receive(chunk);
        while firmware.busy() {
            firmware.tick(|_| {});
        }
        firmware.send_downlink(|bytes| sent.extend_from_slice(bytes));
    }
    firmware.finish();
    firmware
        .send_end(|bytes| sent.extend_from_slice(bytes))
        .expect("the map encodes");
    sent
}

#[test]
fn the_downlink_rebuilds_the_replay_map_in_both_models() {
    let dir = Dir::new("downlink");
    for model in ["paper", "shells"] {
        let stream_model = if model == "paper" {
            StreamModel::Paper
        } else {
            SHELLS
        };
        let (_, capture, replayed) = capture_and_replay(&dir, "car6.pcd", IMAGE, model);
        let downlink = device_downlink(&capture, stream_model);
        // In pieces of every size: the same map.
        for piece in [1, 13, 4096] {
            let mut frames = MapFrames::for_session(SESSION.session);
            for bytes in downlink.chunks(piece) {
                frames.feed(bytes);
            }
            let map = frames.map_file().expect("an end").expect("a whole map");
            assert_eq!(map, replayed, "{model}, pieces of {piece}");
            assert_eq!((frames.counts.refused, frames.counts.lost), (0, 0));
            assert!(frames.counts.entities > 250, "{model}: {:?}", frames.counts);
            // car6's 10,031 points (scanner-sim says so as it writes them), every one mapped.
            assert_eq!(frames.counts.points, 10_031);
            assert!(frames.counts.device_frames > 0);
        }
    }
}

#[test]
fn a_faulty_downlink_never_gives_a_wrong_map() {
    let dir = Dir::new("downlink-faults");
    let (_, capture, replayed) = capture_and_replay(&dir, "car6.pcd", IMAGE, "shells");
    let downlink = device_downlink(&capture, SHELLS);
    let (mut whole, mut incomplete) = (0, 0);
    // Two faults a run on average: a few runs clean, most hit once or a few times.
    let one_in = u32::try_from(downlink.len() / 2).expect("a downlink of a car");
    let mut faulty = 0;
    for seed in 1..=40u64 {
        let mut faults = LineFaults::new(seed, one_in);
        let mut line = Vec::with_capacity(downlink.len() + 8);
        faults.carry(&downlink, |b| line.push(b));
        faulty += u64::from(faults.faults > 0);
        let mut frames = MapFrames::for_session(SESSION.session);
        frames.feed(&line);
        match frames.map_file() {
            Some(Ok(map)) => {
                assert_eq!(map, replayed, "seed {seed}: a map, and not the device's");
                whole += 1;
            }
            Some(Err(DeviceError::Missing { missing })) => {
                assert!(!missing.is_empty());
                assert!(
                    frames.counts.refused + frames.counts.lost > 0,
                    "seed {seed}: entities missing with no fault seen"
                );
                incomplete += 1;
            }
            // The end frame itself was hit: nothing to write, and the host says so.
            None => incomplete += 1,
            Some(Err(e)) => panic!("seed {seed}: {e}"),
        }
    }
    // Faults that hit progress frames leave the map whole; those that hit entities do not.
    assert!(
        whole > 0 && incomplete > 0 && faulty > 30,
        "{whole} whole, {incomplete} incomplete, {faulty} of 40 runs faulty"
    );
}

/// The frames of another session (a previous host's map, sent again by a board that was not
/// reset) never enter the map, whatever their CRC says; a frame from another boot of the
/// device, once the session began, says the device restarted, and there is no map.
#[test]
fn another_sessions_or_boots_frames_never_enter_the_map() {
    let dir = Dir::new("downlink-sessions");
    let (_, capture, shells_map) = capture_and_replay(&dir, "car6.pcd", IMAGE, "shells");
    let (_, _, paper_map) = capture_and_replay(&dir, "car6.pcd", IMAGE, "paper");
    let earlier = Address {
        session: SESSION.session + 1,
        ..SESSION
    };
    let old = device_downlink_as(&capture, StreamModel::Paper, earlier);
    let ours = device_downlink(&capture, SHELLS);
    let mut frames = MapFrames::for_session(SESSION.session);
    frames.feed(&old);
    assert!(
        frames.map_file().is_none(),
        "another session's end was taken"
    );
    let foreign = frames.counts.foreign;
    assert!(foreign > 250, "{:?}", frames.counts);
    frames.feed(&ours);
    let map = frames.map_file().expect("an end").expect("a whole map");
    assert!(map == shells_map && map != paper_map);
    assert_eq!(frames.counts.foreign, foreign);
    // The same session from a later boot, after the first half of this one's frames.
    let rebooted = Address {
        boot: SESSION.boot + 1,
        ..SESSION
    };
    let later = device_downlink_as(&capture, SHELLS, rebooted);
    let mut frames = MapFrames::for_session(SESSION.session);
    frames.feed(&ours[..ours.len() / 2]);
    assert!(frames.broken().is_none());
    frames.feed(&later);
    assert!(
        matches!(
            frames.broken(),
            Some(DeviceError::Rebooted { from: 1, to: 2 })
        ),
        "{:?}",
        frames.broken()
    );
    assert!(frames.map_file().is_none());
}

/// A device that speaks an older downlink (version 0x81, before sessions) is named as such,
/// and none of its frames is taken as this version's, even with its CRC right.
#[test]
fn an_older_protocols_frames_are_named_and_never_taken() {
    let started = DownFrame::Session {
        status: SessionStatus::Started,
        layout: DeviceLayout {
            capacity: 700,
            working: 150,
            model: 1,
        },
    };
    let mut wire = [0u8; MAX_DOWN_FRAME_LEN];
    let n = downlink::encode(SESSION, 0, &started, &mut wire).expect("encodes");
    let mut block = wire[..n - 1].to_vec();
    let raw_len = framing::decode_block(&mut block).expect("a block").len();
    let mut raw = block[..raw_len].to_vec();
    raw[0] = 0x81;
    let body = raw_len - framing::CRC_LEN;
    framing::put_crc(&mut raw, body).expect("room");
    let mut old = [0u8; MAX_DOWN_FRAME_LEN];
    let m = framing::frame_raw(&raw, &mut old).expect("frames");
    let mut frames = MapFrames::for_session(SESSION.session);
    frames.feed(&old[..m]);
    frames.feed(&old[..m]);
    assert_eq!(frames.other_version(), Some(0x81));
    assert!(!frames.started());
    assert_eq!((frames.counts.frames, frames.counts.refused), (0, 2));
    let said = DeviceError::Version(0x81).to_string();
    assert!(said.contains("0x81") && said.contains("0x83"), "{said}");
}

/// A port that gives `bytes` once, then nothing (a line gone quiet); what is written to it is
/// dropped.
struct QuietLine {
    bytes: std::io::Cursor<Vec<u8>>,
}

impl std::io::Read for QuietLine {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match std::io::Read::read(&mut self.bytes, buf)? {
            0 => {
                std::thread::sleep(std::time::Duration::from_millis(5));
                Err(std::io::ErrorKind::WouldBlock.into())
            }
            n => Ok(n),
        }
    }
}

impl std::io::Write for QuietLine {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// A listener whose device goes quiet before its end says which side of the device the
/// silence is on: how many of the stream's frames the device's last progress said it had
/// mapped and refused (none mapped and all refused: the sensor's bytes arrive garbled).
#[test]
fn a_quiet_device_is_named_with_its_last_progress() {
    let from = Address {
        session: 0,
        boot: 3,
    };
    let mut wire = Vec::new();
    for (sequence, (frames, refused)) in [(4, 1), (9, 2), (17, 5)].into_iter().enumerate() {
        let progress = DownFrame::Progress {
            taken: 1_000 * frames,
            frames,
            next: 0,
            refused,
        };
        let mut out = [0u8; MAX_DOWN_FRAME_LEN];
        let n = downlink::encode(from, sequence as u32, &progress, &mut out).expect("encodes");
        wire.extend_from_slice(&out[..n]);
    }
    let mut line = QuietLine {
        bytes: std::io::Cursor::new(wire),
    };
    let mut frames = MapFrames::listening();
    let silence = std::time::Duration::from_millis(300);
    let said = match mema::link::listen::listen(&mut line, &mut frames, silence, |_| {}) {
        Err(e @ DeviceError::Quiet { .. }) => e.to_string(),
        other => panic!("not the quiet device: {other:?}"),
    };
    assert!(
        said.contains("3 frames heard, 0 entities, no end")
            && said.contains("17 stream frames mapped, 5 refused"),
        "{said}"
    );
}
