//! Free, occupied or unknown (issue 29): what a map says of a point, from its surface and the
//! free space it keeps ([`crate::io::free_space`]).
//!
//! A point within the tolerance of an entity's surface, or inside one, is occupied; else it is
//! free where one of the map's scans saw through it (nearer than that pixel's nearest return
//! by [`FREE_MARGIN`]), and unknown anywhere else: behind walls, beyond the sensors' reach, and
//! everywhere in a map that records no free space.

use serde::Serialize;

use crate::io::free_space::FREE_MARGIN;
use crate::io::mapfile::HostMap;
use crate::query::{HostIndex, local};
use mema_core::Point3;

/// What a map says of a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum State {
    Free,
    Occupied,
    Unknown,
}

impl State {
    /// The occupancy probability the held-out score gives it: unknown counts as 0.5.
    pub fn occupancy(self) -> f64 {
        match self {
            State::Free => 0.0,
            State::Occupied => 1.0,
            State::Unknown => 0.5,
        }
    }
}

/// A point's state and its signed distance to the nearest surface (negative inside; NaN in an
/// empty map), with that surface's entity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StateAnswer {
    pub state: State,
    pub signed_distance: f64,
    pub entity: Option<usize>,
}

/// The state of world point `p` in `map` (whose index is `index`), surface within
/// `tolerance` (the map's unit) counting as occupied.
pub fn state_of(map: &HostMap, index: &HostIndex, p: [f64; 3], tolerance: f64) -> StateAnswer {
    let q = local(map, p);
    let nearest = index.nearest(q);
    let signed_distance = nearest.map_or(f64::NAN, |n| n.signed_distance);
    let state = if signed_distance <= tolerance {
        State::Occupied
    } else {
        let point = Point3::new(q[0] as f32, q[1] as f32, q[2] as f32);
        if map
            .free_space
            .iter()
            .any(|image| image.sees_free(point, FREE_MARGIN))
        {
            State::Free
        } else {
            State::Unknown
        }
    };
    StateAnswer {
        state,
        signed_distance,
        entity: nearest.map(|n| n.entity),
    }
}
