//! Observed-free space as range images (issue 29): what a sweep saw through, kept as NanoMap
//! keeps it, in fixed memory.
//!
//! Each sweep keeps, in every pixel of an elevation x azimuth grid around its sensor origin, the
//! least range of its returns, coded in 8 bits on a log scale and rounded down: a point nearer
//! than that, by a margin, lies in space the sweep saw through; one past it, or in a pixel with
//! no return, is not known to be free. Chosen over a voxel octree of the same rays by
//! `scripts/free_space_options.py` (ouster_os1.conf, sweeps 0 and 2 kept, sweep 1's rays held
//! out): at 8 x 64 pixels (512 bytes a sweep) images call 91 % of the points before held-out
//! ends free and 98 % of the points behind walls no ray passed unknown, where a 1 m voxel
//! octree of 9.8 KB called 58 % of those unknown: a voxel's size is a wall's thickness, a pixel
//! has none.

use crate::geometry::Point3;

/// Codes per doubling of the range: 254 codes over ten doublings from an image's nearest range
/// ([`Geometry::near`]; 0.25 m to 256 m for a lidar), each 2.8 % of its range (28 cm at 10 m).
const CODES_PER_OCTAVE: f32 = 25.4;

/// A pixel no return fell in: nothing is known along it.
pub const NO_RETURN: u8 = u8::MAX;

/// The code of range `r` in an image whose nearest range is `near`: the largest code whose
/// range ([`range_of`]) is at most `r`, so an image never claims free space past a return. A
/// return nearer than one code's step past `near`, or NaN, codes as 0, which leaves nothing
/// along its pixel free.
pub fn code(r: f32, near: f32) -> u8 {
    let octaves = libm::log2f(r / near);
    let c = (octaves * CODES_PER_OCTAVE).clamp(0.0, f32::from(NO_RETURN - 1)) as u8;
    // The float rounding may land one code above: step back if it decodes past `r`.
    if c > 0 && range_of(c, near) > r {
        c - 1
    } else {
        c
    }
}

/// The range code `c` stands for (metres): the least range of the returns it was made from,
/// rounded down (0 for code 0).
pub fn range_of(c: u8, near: f32) -> f32 {
    if c == 0 {
        return 0.0;
    }
    near * libm::exp2f(f32::from(c) / CODES_PER_OCTAVE)
}

/// Where a sweep's range image looks: `rows` of elevation between `elevation[0]` and
/// `elevation[1]` (radians), `columns` of azimuth from `azimuth[0]` over `azimuth[1]` radians
/// (at most a whole turn), around `origin` (the map's frame), ranges coded from `near` (the
/// map's unit) over ten doublings. Pixels are stored row by row, lowest elevation first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    pub origin: Point3,
    pub near: f32,
    pub elevation: [f32; 2],
    pub azimuth: [f32; 2],
    pub rows: u16,
    pub columns: u16,
}

impl Geometry {
    /// Pixels in the image.
    pub const fn pixels(&self) -> usize {
        self.rows as usize * self.columns as usize
    }

    /// Whether every field is finite and the spans are not empty: what a decoder checks.
    pub fn is_valid(&self) -> bool {
        let [low, high] = self.elevation;
        let [_, width] = self.azimuth;
        self.origin.is_finite()
            && self.near.is_finite()
            && self.near > 0.0
            && self.azimuth[0].is_finite()
            && low.is_finite()
            && high.is_finite()
            && low < high
            && width > 0.0
            && width <= core::f32::consts::TAU
            && self.rows > 0
            && self.columns > 0
    }

    /// The pixel of `p` and its range from the origin: `None` for a point at the origin, a
    /// non-finite one, or one outside the spans.
    pub fn pixel(&self, p: Point3) -> Option<(usize, f32)> {
        let d = [
            p.x - self.origin.x,
            p.y - self.origin.y,
            p.z - self.origin.z,
        ];
        let r = libm::sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if !(r.is_finite() && r > 0.0) {
            return None;
        }
        let elevation = libm::asinf((d[2] / r).clamp(-1.0, 1.0));
        let index = self.pixel_of(elevation, libm::atan2f(d[1], d[0]))?;
        Some((index, r))
    }

    /// The pixel of a direction, `elevation` and `azimuth` in radians (the azimuth in any
    /// turn); `None` outside the image.
    pub fn pixel_of(&self, elevation: f32, azimuth: f32) -> Option<usize> {
        let [low, high] = self.elevation;
        if !(elevation >= low && elevation <= high && high > low) {
            return None;
        }
        let [start, width] = self.azimuth;
        let wrapped = remainder_of_turn(azimuth - start);
        let turned = if wrapped < 0.0 {
            wrapped + core::f32::consts::TAU
        } else {
            wrapped
        };
        if !(turned <= width && width > 0.0) {
            return None;
        }
        let rows = usize::from(self.rows);
        let columns = usize::from(self.columns);
        // The top and far edges belong to the last row and column.
        let row = ((((elevation - low) / (high - low)) * rows as f32) as usize)
            .min(rows.saturating_sub(1));
        let column = (((turned / width) * columns as f32) as usize).min(columns.saturating_sub(1));
        Some(row * columns + column)
    }
}

/// `x` modulo a whole turn as `libm::fmodf(x, TAU)` gives it (the remainder has `x`'s sign),
/// without its bit-by-bit loop where it is not needed: within a turn the remainder is `x`, and
/// within two turns one subtraction is exact (Sterbenz), so the bits are fmodf's.
fn remainder_of_turn(x: f32) -> f32 {
    use core::f32::consts::TAU;
    if x > -TAU && x < TAU {
        x
    } else if (TAU..2.0 * TAU).contains(&x) {
        x - TAU
    } else if x <= -TAU && x > -2.0 * TAU {
        x + TAU
    } else {
        libm::fmodf(x, TAU)
    }
}

/// Notes a return at `p` in the image `cells` of `geometry`: its pixel's least range is now at
/// most its range.
pub fn add_return(geometry: &Geometry, cells: &mut [u8], p: Point3) {
    if let Some((index, r)) = geometry.pixel(p)
        && let Some(cell) = cells.get_mut(index)
    {
        *cell = (*cell).min(code(r, geometry.near));
    }
}

/// Whether the sweep whose image is `cells` saw through `p`: a return in its pixel lies farther
/// than `p`'s range by more than `margin` metres.
pub fn sees_free(geometry: &Geometry, cells: &[u8], p: Point3, margin: f32) -> bool {
    let Some((index, r)) = geometry.pixel(p) else {
        return false;
    };
    let c = cells.get(index).copied().unwrap_or(NO_RETURN);
    c != NO_RETURN && r < range_of(c, geometry.near) - margin
}

/// A sweep's range image in fixed memory: `N` pixels at most.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeImage<const N: usize> {
    geometry: Geometry,
    cells: [u8; N],
}

impl<const N: usize> RangeImage<N> {
    /// An image with no returns yet; `None` if `geometry` has more pixels than `N`.
    pub fn new(geometry: Geometry) -> Option<Self> {
        (geometry.pixels() <= N).then_some(Self {
            geometry,
            cells: [NO_RETURN; N],
        })
    }

    /// An image of no pixels, to be given its geometry by [`RangeImage::reset`]: a `const fn`,
    /// so a device builds a large image in place in its static rather than on its stack.
    #[inline(always)]
    pub const fn empty() -> Self {
        Self {
            geometry: Geometry {
                origin: Point3::new(0.0, 0.0, 0.0),
                near: 0.0,
                elevation: [0.0; 2],
                azimuth: [0.0; 2],
                rows: 0,
                columns: 0,
            },
            cells: [NO_RETURN; N],
        }
    }

    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// Empties the image in place for `geometry` (a device has no room for a second image);
    /// false, and the image unchanged, if `geometry` has more pixels than `N`.
    pub fn reset(&mut self, geometry: Geometry) -> bool {
        if geometry.pixels() > N {
            return false;
        }
        self.geometry = geometry;
        self.cells.fill(NO_RETURN);
        true
    }

    /// The codes, row by row.
    pub fn cells(&self) -> &[u8] {
        self.cells.get(..self.geometry.pixels()).unwrap_or(&[])
    }

    /// Notes a return of code `code` in pixel `index` (a [`Geometry::pixel`] of this image's):
    /// the pixel keeps the lower code.
    pub fn lower(&mut self, index: usize, code: u8) {
        if index < self.geometry.pixels()
            && let Some(cell) = self.cells.get_mut(index)
        {
            *cell = (*cell).min(code);
        }
    }

    pub fn add_return(&mut self, p: Point3) {
        let n = self.geometry.pixels();
        if let Some(cells) = self.cells.get_mut(..n) {
            add_return(&self.geometry, cells, p);
        }
    }

    pub fn sees_free(&self, p: Point3, margin: f32) -> bool {
        sees_free(&self.geometry, self.cells(), p, margin)
    }
}

#[cfg(test)]
mod tests;
