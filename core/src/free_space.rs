//! Observed-free space as range images (issue 29): what a sweep saw through, kept as NanoMap
//! keeps it, in fixed memory.
//!
//! Each sweep keeps, in every pixel of an elevation x azimuth grid around its sensor origin, the
//! least range of its returns, coded in 8 bits on a log scale and rounded down: a point nearer
//! than that, by a margin, lies in space the sweep saw through; one past it, or in a pixel with
//! no return, is not known to be free. Chosen over a voxel octree of the same rays by
//! `scripts/free_space_options.py` (ouster_os1.conf, sweeps 0 and 2 kept, sweep 1's rays held
//! out): 16 x 128 images, 2 KiB a sweep, call 96 % of the points before held-out ends free and
//! 98 % of the points behind walls no ray passed unknown, where a 1 m voxel octree of 9.8 KB
//! called 58 % of those unknown: a voxel's size is a wall's thickness, a pixel has none.

use crate::geometry::Point3;

/// The shortest range a pixel codes (metres): a return nearer than one code's step past it
/// codes as 0, which leaves nothing along its pixel free.
pub const MIN_RANGE: f32 = 0.25;

/// Codes per doubling of the range: 254 codes from [`MIN_RANGE`] to 256 m, each 2.8 % of its
/// range (28 cm at 10 m).
const CODES_PER_OCTAVE: f32 = 25.4;

/// A pixel no return fell in: nothing is known along it.
pub const NO_RETURN: u8 = u8::MAX;

/// The code of range `r` (metres): the largest code whose range ([`range_of`]) is at most `r`,
/// so an image never claims free space past a return. NaN codes as [`MIN_RANGE`].
pub fn code(r: f32) -> u8 {
    let octaves = libm::log2f(r / MIN_RANGE);
    let c = (octaves * CODES_PER_OCTAVE).clamp(0.0, f32::from(NO_RETURN - 1)) as u8;
    // The float rounding may land one code above: step back if it decodes past `r`.
    if c > 0 && range_of(c) > r { c - 1 } else { c }
}

/// The range code `c` stands for (metres): the least range of the returns it was made from,
/// rounded down (0 for code 0).
pub fn range_of(c: u8) -> f32 {
    if c == 0 {
        return 0.0;
    }
    MIN_RANGE * libm::exp2f(f32::from(c) / CODES_PER_OCTAVE)
}

/// One sweep's range image: `H` rows of elevation between `elevation[0]` and `elevation[1]`
/// (radians), `W` columns of azimuth over the whole turn, around `origin` (the map's frame).
#[derive(Clone, Debug, PartialEq)]
pub struct RangeImage<const H: usize, const W: usize> {
    origin: Point3,
    elevation: [f32; 2],
    cells: [[u8; W]; H],
}

impl<const H: usize, const W: usize> RangeImage<H, W> {
    /// An image with no returns yet. `elevation` spans the sensor's beams (lowest, highest);
    /// directions outside it are never free.
    pub const fn new(origin: Point3, elevation: [f32; 2]) -> Self {
        Self {
            origin,
            elevation,
            cells: [[NO_RETURN; W]; H],
        }
    }

    pub fn origin(&self) -> Point3 {
        self.origin
    }

    pub fn elevation(&self) -> [f32; 2] {
        self.elevation
    }

    /// The codes, row by row (lowest elevation first, azimuth from -pi).
    pub fn cells(&self) -> &[[u8; W]; H] {
        &self.cells
    }

    /// The pixel of `p` and its range from the origin: `None` for a point at the origin, a
    /// non-finite one, or one outside the elevation span.
    fn pixel(&self, p: Point3) -> Option<(usize, usize, f32)> {
        let d = [
            p.x - self.origin.x,
            p.y - self.origin.y,
            p.z - self.origin.z,
        ];
        let r = libm::sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if !(r.is_finite() && r > 0.0) {
            return None;
        }
        let [low, high] = self.elevation;
        let elevation = libm::asinf((d[2] / r).clamp(-1.0, 1.0));
        if !(elevation >= low && elevation <= high && high > low) {
            return None;
        }
        // The top edge belongs to the last row.
        let row = (((elevation - low) / (high - low)) * H as f32) as usize;
        let azimuth = libm::atan2f(d[1], d[0]);
        let turn = (azimuth + core::f32::consts::PI) / core::f32::consts::TAU;
        let column = (turn * W as f32) as usize;
        Some((row.min(H.saturating_sub(1)), column % W.max(1), r))
    }

    /// Notes a return at `p`: its pixel's least range is now at most its range.
    pub fn add_return(&mut self, p: Point3) {
        if let Some((row, column, r)) = self.pixel(p)
            && let Some(cell) = self.cells.get_mut(row).and_then(|c| c.get_mut(column))
        {
            *cell = (*cell).min(code(r));
        }
    }

    /// Whether the sweep saw through `p`: a return in its pixel lies farther than `p`'s range
    /// by more than `margin` metres.
    pub fn sees_free(&self, p: Point3, margin: f32) -> bool {
        let Some((row, column, r)) = self.pixel(p) else {
            return false;
        };
        let c = self
            .cells
            .get(row)
            .and_then(|c| c.get(column))
            .copied()
            .unwrap_or(NO_RETURN);
        c != NO_RETURN && r < range_of(c) - margin
    }
}

#[cfg(test)]
mod tests;
