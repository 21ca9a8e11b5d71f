//! The scanner side: a cloud as a rangefinder would send it, frame by frame.

use anyhow::{Result, bail};
use mema_core::Point3;
use mema_core::link::framing;
use mema_core::link::wire::{
    Content, FrameRepr, FrameReprV2, MAX_FRAME_LEN, MAX_POINTS, MAX_RAW_LEN, QUATERNION_ONE,
    WirePose,
};

/// Points per frame the simulator sends: 100, a round number under [`MAX_POINTS`].
pub const POINTS_PER_FRAME: usize = 100;
/// Millimetres: the unit exponent on the wire.
pub const UNIT_EXPONENT: i8 = -3;

/// Quantises a local-frame point (metres) to wire integers (millimetres, rounded to nearest).
pub fn quantise(p: Point3) -> Result<[i32; 3]> {
    let q = p.to_f64().map(|v| (v * 1000.0).round());
    if q.iter().any(|v| v.is_nan() || v.abs() > i32::MAX as f64) {
        bail!("point {p:?} does not fit the wire's i32 millimetres");
    }
    Ok(q.map(|v| v as i32))
}

/// What the robot's mapper receives for a wire point: exactly the decoder's conversion.
pub fn dequantise(q: [i32; 3]) -> Point3 {
    let scale = mema_core::link::wire::unit_scale(UNIT_EXPONENT).unwrap_or(f64::NAN);
    Point3::new(
        (q[0] as f64 * scale) as f32,
        (q[1] as f64 * scale) as f32,
        (q[2] as f64 * scale) as f32,
    )
}

/// Appends `raw`, COBS-encoded, and the delimiter to `out`.
fn push_framed(out: &mut Vec<u8>, raw: &[u8]) -> Result<()> {
    let start = out.len();
    out.resize(start + MAX_FRAME_LEN, 0);
    let Some(n) = framing::frame_raw(raw, &mut out[start..]) else {
        bail!("COBS buffer too small");
    };
    out.truncate(start + n);
    Ok(())
}

/// Appends one framed (COBS + delimiter) frame to `out`.
pub fn push_frame(
    out: &mut Vec<u8>,
    sequence: u32,
    end_of_stream: bool,
    points: &[[i32; 3]],
) -> Result<()> {
    let repr = FrameRepr {
        sequence,
        end_of_stream,
        unit_exponent: UNIT_EXPONENT,
        points,
    };
    let mut raw = [0u8; MAX_RAW_LEN];
    let Some(len) = repr.emit(&mut raw) else {
        bail!("a frame holds at most {MAX_POINTS} points");
    };
    push_framed(out, raw.get(..len).unwrap_or(&[]))
}

/// The whole wire byte stream for a cloud: a leading delimiter (so a receiver that saw noise
/// resyncs before frame 0), then frames of [`POINTS_PER_FRAME`], the last flagged end of stream.
pub fn encode_stream(points: &[[i32; 3]]) -> Result<Vec<u8>> {
    let mut out = vec![0u8];
    let chunks: Vec<&[[i32; 3]]> = points.chunks(POINTS_PER_FRAME).collect();
    let last = chunks.len().saturating_sub(1);
    for (i, chunk) in chunks.iter().enumerate() {
        push_frame(&mut out, i as u32, i == last, chunk)?;
    }
    if chunks.is_empty() {
        push_frame(&mut out, 0, true, &[])?;
    }
    Ok(out)
}

/// One scan as a moving sensor sends it (version 2): its pose, sensor to world, with the
/// translation in units of `10^pose_exponent` m, then its points in the sensor frame.
#[derive(Clone, Copy, Debug)]
pub struct PosedScan<'a> {
    pub pose: WirePose,
    pub pose_exponent: i8,
    pub points: &'a [[i32; 3]],
}

/// Appends one framed version 2 frame to `out`.
pub fn push_frame_v2(out: &mut Vec<u8>, repr: &FrameReprV2<'_>) -> Result<()> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let Some(len) = repr.emit(&mut raw) else {
        bail!("a frame holds at most {MAX_POINTS} points");
    };
    push_framed(out, raw.get(..len).unwrap_or(&[]))
}

/// The whole version 2 byte stream of a moving sensor: a leading delimiter, then per scan its
/// pose frame (numbered 1, 2, ...) and its points in frames of [`POINTS_PER_FRAME`] naming that
/// pose, in units of `10^unit_exponent` m. The first frame starts the session; the last frame
/// ends the stream.
pub fn encode_posed_stream(scans: &[PosedScan<'_>], unit_exponent: i8) -> Result<Vec<u8>> {
    let mut frames: Vec<FrameReprV2<'_>> = Vec::new();
    for (i, scan) in scans.iter().enumerate() {
        let number = u32::try_from(i + 1)?;
        frames.push(FrameReprV2 {
            sequence: 0,
            end_of_stream: false,
            session_start: false,
            unit_exponent: scan.pose_exponent,
            content: Content::Pose {
                number,
                pose: scan.pose,
            },
        });
        for chunk in scan.points.chunks(POINTS_PER_FRAME) {
            frames.push(FrameReprV2 {
                sequence: 0,
                end_of_stream: false,
                session_start: false,
                unit_exponent,
                content: Content::Points {
                    pose: number,
                    points: chunk,
                },
            });
        }
    }
    let last = frames.len().saturating_sub(1);
    let mut out = vec![0u8];
    for (i, frame) in frames.iter_mut().enumerate() {
        frame.sequence = i as u32;
        frame.session_start = i == 0;
        frame.end_of_stream = i == last;
        push_frame_v2(&mut out, frame)?;
    }
    if frames.is_empty() {
        push_frame_v2(
            &mut out,
            &FrameReprV2 {
                sequence: 0,
                end_of_stream: true,
                session_start: true,
                unit_exponent,
                content: Content::Points {
                    pose: 0,
                    points: &[],
                },
            },
        )?;
    }
    Ok(out)
}

/// A rigid pose in metres and a unit quaternion (scalar last) as the wire carries it: the
/// translation in units of `10^unit_exponent` m, the quaternion in units of 2^-30 with `w >= 0`.
pub fn wire_pose(translation: [f64; 3], rotation: [f64; 4], unit_exponent: i8) -> Result<WirePose> {
    let Some(scale) = mema_core::link::wire::unit_scale(unit_exponent) else {
        bail!("unit exponent {unit_exponent} is outside the wire's range");
    };
    let n = rotation.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n > 0.0 && n.is_finite()) {
        bail!("rotation {rotation:?} is not a quaternion");
    }
    let sign = if rotation[3] < 0.0 { -1.0 } else { 1.0 };
    let one = f64::from(QUATERNION_ONE);
    let q = rotation.map(|v| (sign * v / n * one).round() as i32);
    let mut t = [0i64; 3];
    for (slot, v) in t.iter_mut().zip(translation) {
        let units = (v / scale).round();
        // i64 units reach 9.2 million km even in nanometres: past that is no world frame.
        if units.is_nan() || units.abs() >= 9.0e18 {
            bail!(
                "translation {translation:?} m does not fit the wire's i64 units of 10^{unit_exponent} m"
            );
        }
        *slot = units as i64;
    }
    Ok(WirePose {
        translation: t,
        rotation: q,
    })
}
