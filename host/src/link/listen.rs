//! A listener's side of a mapping device (`mema device --listen`): the map of a sensor wired to
//! the device comes in on a line of its own, in no session. The listener sends no stream; it
//! asks again, on the same line, for the entities that did not arrive intact once the end has
//! come, and for the end when the line has gone quiet without one (the end was lost, or the
//! listener came after it). The map it returns is whole and the device's to the bit, of one
//! boot: a device that restarts is a map lost, never one pieced together from two boots.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use mema_core::link::uplink::{self, MAX_UP_FRAME_LEN, Request, UpFrame};

use super::device::{DeviceError, MapFrames};
use super::port::{ReadOutcome, read_some};
use super::session::{RETRY, whole_or_ask};

/// Receives a map on `port` into `frames` (made by [`MapFrames::listening`]) until it is whole
/// and checked, asking again for what was lost; `report` is called as frames arrive. After
/// `silence` with no frame from the device, gives up with [`DeviceError::Quiet`] (or what
/// the line brought instead: noise, another protocol).
pub fn listen(
    port: &mut (impl Read + Write),
    frames: &mut MapFrames,
    silence: Duration,
    mut report: impl FnMut(&MapFrames),
) -> Result<Vec<u8>, DeviceError> {
    let mut buf = [0u8; 4096];
    let mut heard = Instant::now();
    let mut asked: Option<Instant> = None;
    let mut asks = 0u32;
    loop {
        match read_some(port, &mut buf) {
            ReadOutcome::Bytes(n) => {
                let before = frames.counts.frames;
                frames.feed(&buf[..n]);
                if let Some(e) = frames.broken() {
                    return Err(e);
                }
                if frames.counts.frames != before {
                    heard = Instant::now();
                    report(frames);
                }
            }
            ReadOutcome::Idle => {}
            ReadOutcome::Gone(why) => return Err(DeviceError::Gone(why)),
        }
        if frames.ended() {
            if let Some(done) = whole_or_ask(port, frames, &mut asked, &mut asks) {
                return done;
            }
        } else if heard.elapsed() > 2 * RETRY && asked.is_none_or(|t| t.elapsed() > 2 * RETRY) {
            // Quiet and no end: the stream may have ended with its end lost, or before this
            // listener came (to boot 0 then: whichever boot the device is in answers). A device
            // still mapping ignores the request.
            let mut out = [0u8; MAX_UP_FRAME_LEN];
            let to = frames.address();
            if let Ok(n) = uplink::encode(to, &UpFrame::Request(Request::ResendEnd), &mut out) {
                port.write_all(&out[..n])?;
                port.flush()?;
                frames.counts.ends_asked += 1;
            }
            asked = Some(Instant::now());
        }
        if heard.elapsed() > silence {
            let seconds = silence.as_secs_f64();
            if let Some(version) = frames.other_version() {
                return Err(DeviceError::Version(version));
            }
            let c = &frames.counts;
            if c.frames == 0 && c.refused > 0 {
                return Err(DeviceError::NoValidFrame {
                    seconds,
                    refused: c.refused,
                });
            }
            return Err(DeviceError::Quiet {
                seconds,
                frames: c.frames,
                entities: c.entities,
                mapped: c.device_frames,
                refused: c.device_refused,
            });
        }
    }
}
