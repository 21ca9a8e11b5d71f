//! A host's stream with `--free-space` carves points as `mema map` does
//! ([`crate::mapping::carve`]): each scan is held until [`AFTER`] more have arrived, then judged
//! by those and the [`BEFORE`] scans before it, and its points go on to the mapper, the ones
//! seen through marked. A moving thing's points never reach a cluster, so no floor cluster
//! keeps a walker's legs; the price is a map [`AFTER`] scans behind the sensor, and the scans'
//! points in memory (at most [`MOST_HELD`] a scan). A device, which cannot hold scans, carves
//! clusters instead ([`mema_core::stream::carve`]); the host's stream does both.

use std::collections::VecDeque;

use mema_core::Point3;

use crate::mapping::carve::{SEEN_THROUGH, ScanImages, seen_through};

/// Scans before a scan that judge it (already sent on).
pub const BEFORE: usize = 2;
/// Scans after a scan that judge it: it is held until they have arrived.
pub const AFTER: usize = 2;
/// Points a scan may hold (24 MB of them): past it, a scan passes on uncarved (a stream without
/// poses is one scan without end).
pub const MOST_HELD: usize = 1 << 21;

/// A scan: its sensor, its points while held, its images once it has ended.
struct Scan {
    sensor: Point3,
    points: Vec<Point3>,
    images: Option<ScanImages>,
}

/// The scans held back, and the images of those sent on that still judge others.
#[derive(Default)]
pub struct ScanLag {
    /// Ended scans sent on: their images, at most [`BEFORE`].
    sent: VecDeque<Scan>,
    /// Ended scans held, oldest first: at most [`AFTER`] once the next has ended.
    held: VecDeque<Scan>,
    /// The scan arriving.
    current: Option<Scan>,
    /// The current scan outgrew [`MOST_HELD`]: its points pass straight on.
    passing: bool,
}

impl ScanLag {
    pub fn new() -> Self {
        Self::default()
    }

    /// Point `p`, seen from `sensor` (a new scan if it is not the current one's): hands
    /// `send(sensor, point, seen_through)` every point it lets go, in the order they came.
    pub fn push(&mut self, sensor: Point3, p: Point3, send: &mut impl FnMut(Point3, Point3, bool)) {
        if self.current.as_ref().is_some_and(|c| c.sensor != sensor) {
            self.end_scan(send);
        }
        if self.passing {
            send(sensor, p, false);
            return;
        }
        let current = self.current.get_or_insert_with(|| Scan {
            sensor,
            points: Vec::new(),
            images: None,
        });
        current.points.push(p);
        if current.points.len() >= MOST_HELD {
            // Everything before it goes on first, judged by what has arrived.
            let outgrown = self.current.take();
            while self.send_oldest(send) {}
            if let Some(scan) = outgrown {
                for q in scan.points {
                    send(scan.sensor, q, false);
                }
            }
            self.passing = true;
        }
    }

    /// The stream ended: every scan held goes on, judged by the scans there are.
    pub fn finish(&mut self, send: &mut impl FnMut(Point3, Point3, bool)) {
        self.end_scan(send);
        while self.send_oldest(send) {}
    }

    /// The map started again: what was held is forgotten.
    pub fn restart(&mut self) {
        *self = Self::default();
    }

    /// The current scan ended: it is held, and the oldest held scan goes on once [`AFTER`]
    /// scans follow it.
    fn end_scan(&mut self, send: &mut impl FnMut(Point3, Point3, bool)) {
        self.passing = false;
        let Some(mut scan) = self.current.take() else {
            return;
        };
        scan.images = Some(ScanImages::of(scan.sensor, &scan.points));
        self.held.push_back(scan);
        while self.held.len() > AFTER {
            self.send_oldest(send);
        }
    }

    /// Sends the oldest held scan on, judged by the scans sent before it and those held after
    /// it; false if none is held.
    fn send_oldest(&mut self, send: &mut impl FnMut(Point3, Point3, bool)) -> bool {
        let Some(mut scan) = self.held.pop_front() else {
            return false;
        };
        let mut window: Vec<&ScanImages> =
            self.sent.iter().filter_map(|s| s.images.as_ref()).collect();
        let own = window.len();
        let images = scan.images.take();
        window.extend(images.as_ref());
        window.extend(self.held.iter().filter_map(|s| s.images.as_ref()));
        let carved = if window.len() > SEEN_THROUGH && images.is_some() {
            seen_through(&scan.points, own, &window)
        } else {
            vec![false; scan.points.len()]
        };
        for (p, c) in scan.points.iter().zip(&carved) {
            send(scan.sensor, *p, *c);
        }
        scan.points = Vec::new();
        scan.images = images;
        self.sent.push_back(scan);
        while self.sent.len() > BEFORE {
            self.sent.pop_front();
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall 10 m out along +x, seen from `sensor` at 0.5-degree steps over 40 x 40 degrees,
    /// and, if `ghost`, a patch of returns 5 m out in front of part of it.
    fn scan(sensor: Point3, ghost: bool) -> Vec<Point3> {
        let mut points = Vec::new();
        for i in 0..80 {
            for j in 0..80 {
                let (az, el) = (
                    (-20.0 + 0.5 * i as f32).to_radians(),
                    (-20.0 + 0.5 * j as f32).to_radians(),
                );
                let d = [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()];
                let in_patch = (30..40).contains(&i) && (30..40).contains(&j);
                let range = if ghost && in_patch { 5.0 } else { 10.0 / d[0] };
                points.push(Point3::new(
                    sensor.x + range * d[0],
                    sensor.y + range * d[1],
                    sensor.z + range * d[2],
                ));
            }
        }
        points
    }

    /// Every point sent, in order, with its sensor and whether it was seen through.
    fn run(scans: &[(Point3, Vec<Point3>)]) -> Vec<(Point3, Point3, bool)> {
        let mut lag = ScanLag::new();
        let mut sent = Vec::new();
        let mut send = |s, p, c| sent.push((s, p, c));
        for (sensor, points) in scans {
            for p in points {
                lag.push(*sensor, *p, &mut send);
            }
        }
        lag.finish(&mut send);
        sent
    }

    #[test]
    fn every_point_goes_on_once_in_order_and_a_ghost_two_scans_saw_through_is_marked() {
        let sensors = [0.0f32, 0.1, 0.2, 0.3].map(|y| Point3::new(0.0, y, 0.0));
        let scans: Vec<(Point3, Vec<Point3>)> = sensors
            .iter()
            .enumerate()
            .map(|(i, s)| (*s, scan(*s, i == 0)))
            .collect();
        let sent = run(&scans);
        let expected: Vec<(Point3, Point3)> = scans
            .iter()
            .flat_map(|(s, points)| points.iter().map(move |p| (*s, *p)))
            .collect();
        let got: Vec<(Point3, Point3)> = sent.iter().map(|(s, p, _)| (*s, *p)).collect();
        assert_eq!(got, expected);
        let ghost: Vec<bool> = sent
            .iter()
            .take(scans[0].1.len())
            .zip(&scans[0].1)
            .filter(|(_, p)| p.x < 6.0)
            .map(|((_, _, c), _)| *c)
            .collect();
        assert_eq!(ghost.len(), 100);
        assert!(ghost.iter().all(|c| *c), "the ghost should be seen through");
        let wall_carved = sent.iter().filter(|(_, p, c)| p.x > 9.0 && *c).count();
        assert_eq!(wall_carved, 0, "the wall is there in every scan");
    }

    #[test]
    fn a_scan_is_held_until_two_more_have_arrived() {
        let sensors = [0.0f32, 0.1, 0.2].map(|y| Point3::new(0.0, y, 0.0));
        let mut lag = ScanLag::new();
        let sent = std::cell::Cell::new(0);
        let mut send = |_, _, _| sent.set(sent.get() + 1);
        for s in &sensors {
            for p in scan(*s, false) {
                lag.push(*s, p, &mut send);
            }
        }
        // The third scan is under way: two have ended, and none has two after it.
        assert_eq!(sent.get(), 0);
        lag.push(
            Point3::new(0.0, 0.3, 0.0),
            Point3::new(10.0, 0.0, 0.0),
            &mut send,
        );
        assert_eq!(
            sent.get(),
            6_400,
            "the first scan goes once two have followed it"
        );
        lag.restart();
        lag.finish(&mut send);
        assert_eq!(sent.get(), 6_400, "a restart forgets what was held");
    }

    #[test]
    fn a_scan_past_the_most_held_passes_on_uncarved() {
        let sensor = Point3::new(0.0, 0.0, 0.0);
        let mut lag = ScanLag::new();
        let (sent, marked) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
        let mut send = |_, _, c: bool| {
            sent.set(sent.get() + 1);
            marked.set(marked.get() + usize::from(c));
        };
        for i in 0..MOST_HELD + 10 {
            lag.push(
                sensor,
                Point3::new(1.0 + i as f32 * 1e-6, 0.0, 0.0),
                &mut send,
            );
        }
        assert_eq!(
            sent.get(),
            MOST_HELD + 10,
            "held no longer: each point goes as it comes"
        );
        assert_eq!(marked.get(), 0);
    }
}
