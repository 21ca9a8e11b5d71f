//! The scanner side: a cloud as a rangefinder would send it, frame by frame.

use anyhow::{Result, bail};
use mema_core::Point3;
use mema_core::wire::{FrameRepr, MAX_FRAME_LEN, MAX_POINTS, MAX_RAW_LEN, cobs_encode};

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
    let scale = mema_core::wire::unit_scale(UNIT_EXPONENT).unwrap_or(f64::NAN);
    Point3::new(
        (q[0] as f64 * scale) as f32,
        (q[1] as f64 * scale) as f32,
        (q[2] as f64 * scale) as f32,
    )
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
    let start = out.len();
    out.resize(start + MAX_FRAME_LEN, 0);
    let Some(n) = cobs_encode(raw.get(..len).unwrap_or(&[]), &mut out[start..]) else {
        bail!("COBS buffer too small");
    };
    out.truncate(start + n);
    out.push(0);
    Ok(())
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
