//! What `mema draw --around X,Y,Z --radius R` draws: the points within a ball and the entities
//! centred in it. A spinning lidar's sweep reaches hundreds of metres in a few strays while its
//! street lies within tens; framed whole, the street is a blob of a few pixels. The ball is in
//! world coordinates (the cloud's, in metres), so one centre and radius crop the cloud and any
//! map of it alike.

use crate::io::cloud::LocalCloud;
use crate::io::mapfile::HostMap;

/// A ball in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ball {
    pub centre: [f64; 3],
    pub radius: f64,
}

/// Why a ball crops nothing to draw.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CropError {
    #[error("--radius {0} is not a positive length in metres")]
    Radius(f64),
    #[error("--around has a coordinate that is not finite")]
    Centre,
    #[error("no point of the cloud lies within {radius} m of ({}, {}, {})", centre[0], centre[1], centre[2])]
    NoPoints { centre: [f64; 3], radius: f64 },
}

impl Ball {
    /// The ball, if its centre is finite and its radius positive.
    pub fn new(centre: [f64; 3], radius: f64) -> Result<Self, CropError> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(CropError::Radius(radius));
        }
        if !centre.iter().all(|c| c.is_finite()) {
            return Err(CropError::Centre);
        }
        Ok(Self { centre, radius })
    }

    fn holds(&self, p: [f64; 3]) -> bool {
        let d2: f64 = (0..3).map(|j| (p[j] - self.centre[j]).powi(2)).sum();
        d2 <= self.radius * self.radius
    }

    /// The cloud's points within the ball, in the same local frame (nothing is rounded again);
    /// the counts of what the read dropped are kept.
    pub fn cloud(&self, cloud: &LocalCloud) -> Result<LocalCloud, CropError> {
        let o = cloud.origin;
        let points: Vec<_> = cloud
            .points
            .iter()
            .filter(|p| {
                let q = p.to_f64();
                self.holds([o[0] + q[0], o[1] + q[1], o[2] + q[2]])
            })
            .copied()
            .collect();
        if points.is_empty() {
            return Err(CropError::NoPoints {
                centre: self.centre,
                radius: self.radius,
            });
        }
        Ok(LocalCloud {
            points,
            // A picture's ball of points, not rays.
            sensors: Default::default(),
            ..cloud.clone()
        })
    }

    /// The map's entities whose centre lies within the ball (an entity reaching in from
    /// outside is left out, as its points are).
    pub fn map(&self, map: &HostMap) -> HostMap {
        HostMap {
            entities: map
                .entities
                .iter()
                .filter(|e| self.holds(map.world_center(&e.entity)))
                .copied()
                .collect(),
            ..map.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ball_keeps_what_lies_in_it_in_world_coordinates() {
        let cloud =
            LocalCloud::from_world(&[[100.0, 0.0, 0.0], [103.0, 4.0, 0.0], [90.0, 0.0, 0.0]]);
        let ball = Ball::new([100.0, 0.0, 0.0], 5.0).unwrap();
        let kept = ball.cloud(&cloud).unwrap();
        let world = kept.world_points();
        assert_eq!(world, [[100.0, 0.0, 0.0], [103.0, 4.0, 0.0]]);
        assert_eq!(kept.origin, cloud.origin);
        assert!(Ball::new([0.0; 3], 1.0).unwrap().cloud(&cloud).is_err());
        assert!(Ball::new([0.0; 3], 0.0).is_err());
        assert!(Ball::new([f64::NAN, 0.0, 0.0], 1.0).is_err());
    }
}
