//! What the readers share below the formats: binary number types, and the collector that
//! turns a reader's coordinates into a centred f32 cloud.

use super::outliers::{self, OutlierDrops, Outliers};
use super::{Cloud, Ctx, Format, ReadError};
use crate::io::units::FileUnit;
use crate::kdtree::Entry;

/// A binary number type, as PLY and PCD declare them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

impl Scalar {
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    pub fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value at the start of `bytes`, or `None` if `bytes` is too short. 64-bit integers
    /// round to the nearest f64; a count too large to be exact is too large for any file.
    #[inline]
    pub fn read(self, bytes: &[u8], endian: Endian) -> Option<f64> {
        macro_rules! get {
            ($t:ty) => {{
                let raw = *bytes.first_chunk::<{ size_of::<$t>() }>()?;
                (match endian {
                    Endian::Little => <$t>::from_le_bytes(raw),
                    Endian::Big => <$t>::from_be_bytes(raw),
                }) as f64
            }};
        }
        Some(match self {
            Scalar::I8 => get!(i8),
            Scalar::U8 => get!(u8),
            Scalar::I16 => get!(i16),
            Scalar::U16 => get!(u16),
            Scalar::I32 => get!(i32),
            Scalar::U32 => get!(u32),
            Scalar::I64 => get!(i64),
            Scalar::U64 => get!(u64),
            Scalar::F32 => get!(f32),
            Scalar::F64 => get!(f64),
        })
    }
}

/// A point's f64 coordinates kept as the bits of each in two 4-byte words: 24 bytes with the
/// alignment of `[f32; 3]`. Mapping a Vec of these to `[f32; 3]` is then collected into the
/// same allocation (std reuses it when the alignments match and the new item is no larger), so
/// the f32 cloud never sits next to its f64 staging.
#[derive(Clone, Copy, Default)]
pub(crate) struct Wide([u32; 6]);

impl Wide {
    pub fn new(p: [f64; 3]) -> Self {
        let mut w = Wide::default();
        for (axis, c) in p.into_iter().enumerate() {
            w.set(axis, c);
        }
        w
    }

    /// Sets coordinate `axis` (0, 1 or 2).
    #[inline]
    pub fn set(&mut self, axis: usize, c: f64) {
        let bits = c.to_bits();
        if let Some(pair) = self.0.get_mut(2 * axis..2 * axis + 2) {
            pair.copy_from_slice(&[bits as u32, (bits >> 32) as u32]);
        }
    }

    #[inline]
    pub fn get(self) -> [f64; 3] {
        let [x0, x1, y0, y1, z0, z1] = self.0;
        let f = |lo: u32, hi: u32| f64::from_bits(u64::from(lo) | u64::from(hi) << 32);
        [f(x0, x1), f(y0, y1), f(z0, z1)]
    }
}

/// Collects points, counting slots and dropping non-finite ones, then centres them.
///
/// While every coordinate is exactly an f32 (binary float clouds, the common case) the points
/// are held as f32, 12 bytes each, and centred in place. The first coordinate that is not an
/// exact f32 (text, doubles) moves them to f64 for the rest, as [`Wide`], which is centred into
/// f32 in the same allocation. Either way the cloud exists once, never as an f64 staging copy
/// beside the f32 result. Centring computes `(p - origin) as f32` from the same f64 value
/// either way, so the bits do not depend on it.
pub(crate) struct Points {
    narrow: Vec<[f32; 3]>,
    wide: Vec<Wide>,
    lo: [f64; 3],
    hi: [f64; 3],
    slots: usize,
    dropped: usize,
    by_class: super::ClassDrops,
    /// Where the sensor was, in the file's coordinates, if the file says (PCD `VIEWPOINT`, a
    /// KITTI scan): points at it are no-returns ([`Self::set_sensor`]).
    sensor: Option<[f64; 3]>,
}

/// Reserves room for exactly `n` more items: a refusal is an error naming what was wanted, not
/// an abort, since `n` comes from a header (bounded by the file's bytes, but a large file may
/// still declare more than the machine has).
fn reserve<T>(ctx: Ctx, v: &mut Vec<T>, n: usize, what: &str) -> Result<(), ReadError> {
    crate::heap::fallible(|| v.try_reserve_exact(n))
        .map_err(|_| ctx.out_of_memory(format!("{n} {what} of {} bytes", size_of::<T>())))
}

impl Points {
    pub fn new() -> Self {
        Points {
            narrow: Vec::new(),
            wide: Vec::new(),
            lo: [f64::INFINITY; 3],
            hi: [f64::NEG_INFINITY; 3],
            slots: 0,
            dropped: 0,
            by_class: super::ClassDrops::default(),
            sensor: None,
        }
    }

    /// Says where the sensor was (in the file's coordinates): [`Self::finish`] then drops the
    /// points within the screening's `min_range` of it as no-returns, since lidar drivers write
    /// a beam that came back empty as the sensor's own position (0, 0, 0), and keeps the sensor
    /// in the cloud, so every point is a ray from it.
    pub fn set_sensor(&mut self, sensor: [f64; 3]) {
        self.sensor = Some(sensor);
    }

    /// Drops the points within `min_range` (metres; `scale` takes the file's unit to metres)
    /// of the sensor, and bounds the rest again; returns how many went.
    fn drop_no_returns(&mut self, min_range: f64, scale: f64) -> usize {
        let Some(sensor) = self.sensor else { return 0 };
        let returned = |p: [f64; 3]| {
            let d2: f64 = (0..3)
                .map(|j| (p[j] - sensor[j]) * (p[j] - sensor[j]))
                .sum();
            d2.sqrt() * scale > min_range
        };
        let before = self.narrow.len() + self.wide.len();
        self.narrow.retain(|p| returned(p.map(f64::from)));
        self.wide.retain(|w| returned(w.get()));
        let gone = before - self.narrow.len() - self.wide.len();
        if gone > 0 {
            self.rebound();
        }
        gone
    }

    /// The bounds of the points kept, after some were left out.
    fn rebound(&mut self) {
        (self.lo, self.hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let wide = self.wide.iter().map(|w| w.get());
        for p in self.narrow.iter().map(|p| p.map(f64::from)).chain(wide) {
            for ((lo, hi), c) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(c);
                *hi = hi.max(c);
            }
        }
    }

    /// `capacity` must already be bounded by what the file's bytes could hold.
    pub fn with_capacity(ctx: Ctx, capacity: usize) -> Result<Self, ReadError> {
        let mut points = Points::new();
        reserve(ctx, &mut points.narrow, capacity, "points")?;
        Ok(points)
    }

    /// Makes room for `n` more points, for a reader whose count is known only as it decodes
    /// (LAZ): when they do not fit, the buffer in use grows to twice the points it holds, or by
    /// `n` if that is more, but by no more than `most`, the points the header still claims. A
    /// true claim is then met with nothing over, and a false one costs at most twice the points
    /// the data gave. A refused allocation is [`ReadError::OutOfMemory`].
    pub fn grow(&mut self, ctx: Ctx, n: usize, most: usize) -> Result<(), ReadError> {
        fn grow<T>(ctx: Ctx, v: &mut Vec<T>, n: usize, most: usize) -> Result<(), ReadError> {
            if v.capacity() - v.len() >= n {
                return Ok(());
            }
            let more = v.len().max(n).min(most.max(n));
            reserve(ctx, v, more, "points")
        }
        // `push` fills `wide` once it has a point, and `narrow` until then.
        if self.wide.is_empty() {
            grow(ctx, &mut self.narrow, n, most)
        } else {
            grow(ctx, &mut self.wide, n, most)
        }
    }

    #[inline]
    /// A slot whose point its class leaves out: counted as a slot, never a point.
    pub fn leave_out(&mut self, why: super::classes::LeftOut) {
        self.slots += 1;
        self.by_class.note(why);
    }

    pub fn push(&mut self, p: [f64; 3]) {
        self.slots += 1;
        if p.iter().all(|c| c.is_finite()) {
            for ((lo, hi), c) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(c);
                *hi = hi.max(c);
            }
            let narrow = p.map(|c| c as f32);
            if self.wide.is_empty() && narrow.iter().zip(p).all(|(&n, c)| n as f64 == c) {
                self.narrow.push(narrow);
            } else {
                if self.wide.is_empty() {
                    let narrow = std::mem::take(&mut self.narrow);
                    let capacity = narrow.capacity();
                    // Text turns wide at its first point: with nothing to carry over, the f32
                    // buffer goes before the f64 one comes, so the two never coexist.
                    let carried: Vec<Wide> = if narrow.is_empty() {
                        drop(narrow);
                        Vec::with_capacity(capacity)
                    } else {
                        let mut wide = Vec::with_capacity(capacity);
                        wide.extend(narrow.iter().map(|q| Wide::new(q.map(f64::from))));
                        wide
                    };
                    self.wide = carried;
                }
                self.wide.push(Wide::new(p));
            }
        } else {
            self.dropped += 1;
        }
    }

    /// Adopts slots already decoded in place (an organized cloud's NaN slots included): the
    /// finite ones are moved to the front of the same allocation, in slot order, exactly as
    /// pushing each slot would keep them. The coordinates must be exact f32 values.
    pub fn from_slots_narrow(mut slots: Vec<[f32; 3]>) -> Self {
        let mut points = Points::new();
        let kept = points.compact(&mut slots, |p| p.map(f64::from));
        slots.truncate(kept);
        points.narrow = slots;
        points
    }

    /// The same for coordinates that need f64.
    pub fn from_slots_wide(mut slots: Vec<Wide>) -> Self {
        let mut points = Points::new();
        let kept = points.compact(&mut slots, Wide::get);
        slots.truncate(kept);
        points.wide = slots;
        points
    }

    /// Moves the finite slots to the front, counting and bounding them; returns how many.
    fn compact<T: Copy>(&mut self, slots: &mut [T], wide: impl Fn(T) -> [f64; 3]) -> usize {
        let mut kept = 0;
        for read in 0..slots.len() {
            let Some(&slot) = slots.get(read) else { break };
            self.slots += 1;
            let p = wide(slot);
            if !p.iter().all(|c| c.is_finite()) {
                self.dropped += 1;
                continue;
            }
            for ((lo, hi), c) in self.lo.iter_mut().zip(&mut self.hi).zip(p) {
                *lo = lo.min(c);
                *hi = hi.max(c);
            }
            if let Some(to) = slots.get_mut(kept) {
                *to = slot;
            }
            kept += 1;
        }
        kept
    }

    /// Drops the points `ctx`'s outlier rule finds isolated (lengths times `scale`, in the
    /// unit they will be mapped in) and refuses a cloud f32 cannot hold at its spacing; the bounds
    /// then are the kept points'. Nothing is done for [`Outliers::Unchecked`].
    fn screen(&mut self, ctx: Ctx, scale: f64) -> Result<OutlierDrops, ReadError> {
        let rule = ctx.screening().outliers;
        if rule == Outliers::Unchecked {
            return Ok(OutlierDrops::default());
        }
        // One of the two holds the points (`push` moves them to `wide` at the first that needs
        // it); a tree of f32 entries for exact-f32 clouds is half the size.
        let verdict = if self.wide.is_empty() {
            let mut entries = Vec::new();
            reserve(
                ctx,
                &mut entries,
                self.narrow.len(),
                "points to screen for outliers",
            )?;
            entries.extend(
                self.narrow
                    .iter()
                    .zip(0u32..)
                    .map(|(&point, index)| Entry { point, index }),
            );
            outliers::screen(entries, scale, rule)
        } else {
            let mut entries = Vec::new();
            reserve(
                ctx,
                &mut entries,
                self.wide.len(),
                "points to screen for outliers",
            )?;
            entries.extend(self.wide.iter().zip(0u32..).map(|(w, index)| Entry {
                point: w.get(),
                index,
            }));
            outliers::screen(entries, scale, rule)
        }
        .map_err(|loss| ReadError::Precision {
            name: ctx.name(),
            loss,
        })?;
        if verdict.drops.dropped > 0 {
            // The indices run over `narrow` then `wide`, as the entries did (one of them is empty).
            let mut index = 0;
            self.narrow.retain(|_| {
                index += 1;
                verdict.keeps(index - 1)
            });
            self.wide.retain(|_| {
                index += 1;
                verdict.keeps(index - 1)
            });
            self.rebound();
        }
        Ok(verdict.drops)
    }

    pub fn finish(self, ctx: Ctx, format: Format) -> Result<Cloud, ReadError> {
        self.finish_in(ctx, format, None)
    }

    /// [`Self::finish`] for a file that says its unit (`None`: it says nothing); the points are
    /// scaled to metres here if `ctx` asks for metres.
    pub fn finish_in(
        mut self,
        ctx: Ctx,
        format: Format,
        unit: Option<FileUnit>,
    ) -> Result<Cloud, ReadError> {
        let units = ctx.units(unit.as_ref())?;
        // A scale of 1 is skipped, not multiplied by, so metres read bit for bit as before.
        let scale = units.as_ref().map(|u| u.unit.metres).filter(|&s| s != 1.0);
        let scaled = |c: f64| scale.map_or(c, |s| c * s);
        // Before the outlier screening: a sphere of no-returns is not isolated, and would
        // stand in its neighbours' statistics.
        let no_returns = self.drop_no_returns(ctx.screening().min_range, scale.unwrap_or(1.0));
        if self.wide.is_empty() && self.narrow.is_empty() {
            let (name, slots) = (ctx.name(), self.slots);
            return Err(ReadError::NoFinitePoints { name, slots });
        }
        let outliers = self.screen(ctx, scale.unwrap_or(1.0))?;
        // Positive scales keep the order, so the scaled bounds are the bounds scaled.
        let (lo, hi) = (self.lo.map(scaled), self.hi.map(scaled));
        // Halving before adding keeps the centre and the half-extent finite even for
        // coordinates near f64::MAX.
        let origin: [f64; 3] = std::array::from_fn(|i| lo[i] / 2.0 + hi[i] / 2.0);
        for (axis, (lo, hi)) in ["x", "y", "z"].iter().zip(lo.iter().zip(&hi)) {
            if !(lo.is_finite() && hi.is_finite()) || hi / 2.0 - lo / 2.0 > f64::from(f32::MAX) {
                return Err(ctx.unsupported(format!(
                    "{axis} spans {lo:e} to {hi:e}, beyond f32 even after centring"
                )));
            }
        }
        let local = |p: [f64; 3]| std::array::from_fn(|i| (scaled(p[i]) - origin[i]) as f32);
        let mut points = if self.wide.is_empty() {
            let mut points = self.narrow;
            for p in points.iter_mut() {
                *p = local(p.map(f64::from));
            }
            points
        } else {
            self.wide.into_iter().map(|p| local(p.get())).collect()
        };
        // An organized cloud was allocated for all its slots, NaN ones included, and f64
        // staging for twice the f32 points; handing the rest back keeps the cloud at 12 bytes
        // a point for the whole pipeline (a shrinking realloc, which glibc does in place).
        points.shrink_to_fit();
        Ok(Cloud {
            origin,
            points,
            slots: self.slots,
            dropped_non_finite: self.dropped,
            dropped_by_class: self.by_class,
            outliers,
            format,
            unit,
            units,
            sensor: self.sensor.map(|s| s.map(scaled)),
            no_returns,
        })
    }
}
