//! Questions for a mapping device's finished map (`mema device --queries N`): the nearest
//! surface to a point and the first surface along a ray, asked over the link
//! ([`mema_core::link::uplink::Request::Query`]) and answered by the device with the core's no_std
//! queries on its own map. Each answer is checked against the same query computed here over
//! the entities the device sent, and its cost comes back in the device's timer ticks.

use std::io::{Read, Write};
use std::time::Instant;

use mema_core::geometry::Entity;
use mema_core::link::uplink::{self, MAX_UP_FRAME_LEN, Request, UpFrame};
use mema_core::query::brute_force;
use mema_core::rng::{Pcg32, stream_rng, uniform};
use serde::Serialize;

use super::device::{DeviceError, MapFrames};
use super::port::{ReadOutcome, read_some};
use super::session::{MAX_ASKS, RETRY};

/// How far a ray is followed, metres.
pub const RAY_REACH: f64 = 1_000.0;

/// What the device's answers were, and what they cost it.
#[derive(Clone, Debug, Default, Serialize)]
pub struct QueryReport {
    pub asked: u32,
    /// Answers equal to the host's, bit for bit (entity and distance).
    pub agreed: u32,
    /// Instructions a query on the device (its timer's ticks by its calibration), by kind.
    pub nearest_instructions: Option<f64>,
    pub ray_instructions: Option<f64>,
}

/// One query: a point near an entity of the map (within a metre of its centre), and for a ray
/// a direction drawn on the sphere.
fn query(rng: &mut Pcg32, entities: &[Entity], ray: bool) -> ([f32; 3], [f32; 3]) {
    let mut unit = || (uniform(rng) * 2.0 - 1.0) as f32;
    let pick = (unit() * 0.5 + 0.5) * entities.len().saturating_sub(1) as f32;
    let c = entities
        .get(pick as usize)
        .map_or([0.0; 3], |e| e.center.to_array());
    let point = [c[0] + unit(), c[1] + unit(), c[2] + unit()];
    let mut d = [unit(), unit(), unit()];
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-3);
    d.iter_mut().for_each(|v| *v /= n);
    (point, if ray { d } else { [0.0; 3] })
}

/// The host's own answer: entity (`u32::MAX`: none) and value.
fn expected(entities: &[Entity], ray: bool, point: [f32; 3], direction: [f32; 3]) -> (u32, f64) {
    let p = point.map(f64::from);
    if ray {
        let d = direction.map(f64::from);
        brute_force::ray_cast(entities, p, d, RAY_REACH)
            .map_or((u32::MAX, f64::INFINITY), |h| (h.entity as u32, h.t))
    } else {
        brute_force::nearest(entities, p).map_or((u32::MAX, f64::INFINITY), |n| {
            (n.entity as u32, n.signed_distance)
        })
    }
}

/// Asks `count` queries (alternately nearest surface and ray, seeded), one at a time, each
/// again after [`RETRY`] without an answer, and checks the answers.
pub fn ask(
    port: &mut (impl Read + Write),
    frames: &mut MapFrames,
    count: u32,
    seed: u64,
) -> Result<QueryReport, DeviceError> {
    let Some(entities) = frames.entities() else {
        return Err(DeviceError::Missing {
            missing: frames.missing(),
        });
    };
    let mut rng = stream_rng(seed, 0x5155_4552);
    let mut report = QueryReport::default();
    let (mut nearest_ticks, mut ray_ticks) = (0u64, 0u64);
    let mut buf = [0u8; 4096];
    let mut out = [0u8; MAX_UP_FRAME_LEN];
    for number in 0..count {
        let ray = number % 2 == 1;
        let (point, direction) = query(&mut rng, &entities, ray);
        let frame = UpFrame::Request(Request::Query {
            number,
            ray,
            point,
            direction,
        });
        let n = uplink::encode(frames.address(), &frame, &mut out).map_err(DeviceError::Encode)?;
        let mut asks = 0;
        let mut asked = None::<Instant>;
        let answer = loop {
            if let Some(a) = frames.answer(number) {
                break a;
            }
            if asked.is_none_or(|t| t.elapsed() > RETRY) {
                if asks == MAX_ASKS {
                    return Err(DeviceError::Silent {
                        seconds: (RETRY * MAX_ASKS).as_secs_f64(),
                        sent: number as usize,
                        total: count as usize,
                    });
                }
                port.write_all(&out[..n])?;
                port.flush()?;
                asks += 1;
                asked = Some(Instant::now());
            }
            match read_some(port, &mut buf) {
                ReadOutcome::Bytes(got) => {
                    frames.feed(&buf[..got]);
                    if let Some(e) = frames.broken() {
                        return Err(e);
                    }
                }
                ReadOutcome::Idle => {}
                ReadOutcome::Gone(why) => return Err(DeviceError::Gone(why)),
            }
        };
        let (entity, value, ticks) = answer;
        report.asked += 1;
        let (want_entity, want_value) = expected(&entities, ray, point, direction);
        if entity == want_entity && value.to_bits() == want_value.to_bits() {
            report.agreed += 1;
        }
        *(if ray {
            &mut ray_ticks
        } else {
            &mut nearest_ticks
        }) += u64::from(ticks);
    }
    if let Some(per_tick) = frames.instructions_per_tick() {
        let each = |ticks: u64, n: u32| (n > 0).then(|| ticks as f64 * per_tick / f64::from(n));
        report.nearest_instructions = each(nearest_ticks, count.div_ceil(2));
        report.ray_instructions = each(ray_ticks, count / 2);
    }
    Ok(report)
}
