use mema_core::link::downlink::{self, DeviceTiming, DownFrame, MAX_DOWN_FRAME_LEN, MapEnd};
use mema_core::map::Layout;

use super::*;

fn encoded(from: Address, sequence: u32, frame: &DownFrame) -> Vec<u8> {
    let mut out = [0u8; MAX_DOWN_FRAME_LEN];
    let n = downlink::encode(from, sequence, frame, &mut out).expect("encodes");
    out[..n].to_vec()
}

fn resend_end(to: Address) -> Vec<u8> {
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    let n = uplink::encode(to, &UpFrame::Request(Request::ResendEnd), &mut out).expect("encodes");
    out[..n].to_vec()
}

/// A listener that has heard an empty map's end (10 points, 1 frame) and nothing before it,
/// from `FROM`.
fn ended_without_timing() -> MapFrames {
    let end = DownFrame::End(MapEnd {
        entities: 0,
        layout: Layout::AxisAligned,
        shift: [0.0; 3],
        origin: [0.0; 3],
        map_len: 0,
        map_crc: 0,
        points: 10,
        frames: 1,
    });
    let mut frames = MapFrames::listening();
    frames.feed(&encoded(FROM, 0, &end));
    frames
}

const FROM: Address = Address {
    session: 0,
    boot: 1,
};

/// A faulty line can take the timing frame a device sends just before its end: the end alone
/// asks for both again, a few times, and a timing that comes after the end still gives the
/// session its cost.
#[test]
fn an_end_without_its_timing_asks_for_the_end_again() {
    let mut frames = ended_without_timing();
    assert!(frames.ended() && frames.lacks_timing());

    let (mut asked, mut asks) = (None, 0);
    let mut port = Vec::new();
    assert!(whole_or_ask(&mut port, &mut frames, &mut asked, &mut asks).is_none());
    assert_eq!(port, resend_end(frames.address()));
    assert_eq!(frames.counts.ends_asked, 1);
    // Within a retry's wait, nothing more is sent.
    assert!(whole_or_ask(&mut port, &mut frames, &mut asked, &mut asks).is_none());
    assert_eq!(frames.counts.ends_asked, 1);

    let timing = DownFrame::Timing(DeviceTiming {
        busy_ticks: 500,
        calib_ticks: 1,
        calib_insns: 2,
        ..DeviceTiming::default()
    });
    frames.feed(&encoded(FROM, 1, &timing));
    assert!(!frames.lacks_timing());
    let per_point = frames.counts.instructions.map(|i| i.per_point);
    assert_eq!(
        per_point,
        Some(100.0),
        "500 ticks of 2 instructions over 10 points"
    );
    // Whole now: the session ends (here with the empty map's mismatch), asking nothing more.
    port.clear();
    assert!(whole_or_ask(&mut port, &mut frames, &mut asked, &mut asks).is_some());
    assert!(port.is_empty());
}

/// A faulty line that cost entities asked for again still leaves the timing its own asks
/// (`tests/tests/board_sensor.rs` once lost a board's timing so: 13 entity asks had spent them).
#[test]
fn entities_asked_again_leave_the_timing_its_asks() {
    let mut frames = ended_without_timing();
    let mut asks = 13;
    let mut port = Vec::new();
    assert!(whole_or_ask(&mut port, &mut frames, &mut None, &mut asks).is_none());
    assert_eq!(port, resend_end(frames.address()));
    assert_eq!((frames.counts.ends_asked, asks), (1, 13));
}

/// A device that never sends its timing costs the session TIMING_ASKS asks, then the map.
#[test]
fn a_timing_that_never_comes_is_asked_for_a_bounded_number_of_times() {
    let mut frames = ended_without_timing();
    let mut asks = 0;
    let mut port = Vec::new();
    for _ in 0..TIMING_ASKS {
        // Each time past a retry's wait.
        assert!(whole_or_ask(&mut port, &mut frames, &mut None, &mut asks).is_none());
    }
    assert_eq!(frames.counts.ends_asked, u64::from(TIMING_ASKS));
    assert!(whole_or_ask(&mut port, &mut frames, &mut None, &mut asks).is_some());
    assert_eq!(frames.counts.ends_asked, u64::from(TIMING_ASKS));
}
