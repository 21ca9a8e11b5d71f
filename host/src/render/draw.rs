//! `mema draw`: a headless orthographic render of a cloud and its map(s) into an RGB raster.
//!
//! Entities are ray-cast per pixel (exact silhouettes and depths, no tessellation), points are
//! depth-tested dots drawn over them, and text comes from the bitmap font of [`Raster`]. The
//! projection is [`Frame`]'s (see [`super::camera`]).
//!
//! Cost: each entity visits, row by row, only the pixels its silhouette can cover (the
//! interval a row cuts from its outline, found in closed form), so a picture costs its pixels,
//! its entities and the area they cover, never entities times pixels.

use mema_core::EntityKind;
use serde::Serialize;

use super::export::kind_colour;
use crate::io::mapfile::HostMap;

use super::camera::dot;
pub use super::camera::{Camera, Extent, Frame, Up, View};
pub use super::raster::{BACKGROUND, Raster};

/// The cloud's points.
pub const POINT_COLOUR: [u8; 3] = [25, 25, 25];
/// Text and scale bar.
pub const INK: [u8; 3] = [0, 0, 0];
/// Diffuse shading spans `[AMBIENT, 1]` times the kind's colour.
pub const AMBIENT: f64 = 0.35;

/// How entities are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Style {
    /// Lambert-shaded solids in the kind's colour.
    Shaded,
    /// Silhouettes only, over the points.
    Outline,
}

/// A box [min, max] in an entity's axes (`R^T x`, x local to the frame's origin: turned, not
/// moved); the entity is cut by it only along its infinite axes. For an axis-aligned entity
/// these are the frame's own axes.
pub type Clip = ([f64; 3], [f64; 3]);

/// Where a ray `p + t forward` is inside an entity (its infinite axes cut by `clip`): the
/// entry depth and the surface normal there, or `None`. Everything is in the entity's axes,
/// where its quadric and its clip are axis-aligned.
fn hit(p: [f64; 3], f: [f64; 3], c: [f64; 3], w: [f64; 3], clip: &Clip) -> Option<(f64, [f64; 3])> {
    let o = [0, 1, 2].map(|j| p[j] - c[j]);
    let a: f64 = (0..3).map(|j| w[j] * f[j] * f[j]).sum();
    let b: f64 = (0..3).map(|j| w[j] * o[j] * f[j]).sum();
    let cc: f64 = (0..3).map(|j| w[j] * o[j] * o[j]).sum::<f64>() - 1.0;
    let (mut t0, mut t1) = if a > 1e-12 {
        let disc = b * b - a * cc;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        ((-b - root) / a, (-b + root) / a)
    } else if cc <= 0.0 {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        return None;
    };
    let quadric_entry = t0;
    let mut face = None;
    for j in 0..3 {
        if w[j] == 0.0 {
            let (lo, hi) = (clip.0[j], clip.1[j]);
            if f[j].abs() < 1e-12 {
                if p[j] < lo || p[j] > hi {
                    return None;
                }
                continue;
            }
            let (mut s0, mut s1) = ((lo - p[j]) / f[j], (hi - p[j]) / f[j]);
            if s0 > s1 {
                std::mem::swap(&mut s0, &mut s1);
            }
            if s0 > t0 {
                t0 = s0;
                face = Some(j);
            }
            t1 = t1.min(s1);
        }
    }
    if t0 > t1 || !t0.is_finite() {
        return None;
    }
    let normal = match face {
        Some(j) if t0 > quadric_entry => {
            let mut n = [0.0; 3];
            n[j] = -f[j].signum();
            n
        }
        _ => [0, 1, 2].map(|j| w[j] * (o[j] + t0 * f[j])),
    };
    Some((t0, normal))
}

/// The frame seen from an entity's axes: its camera turned by `R^T`, so that projecting or
/// unprojecting there is `R^T` of the world's (`dot(R^T a, R^T b) = dot(a, b)`). The identity
/// turns nothing, so axis-aligned entities keep their pixels bit for bit.
fn in_entity_axes(frame: &Frame, rotation: &mema_core::Rotation) -> Frame {
    let c = frame.camera;
    let turn = |v| rotation.inverse_rotate(v);
    Frame {
        camera: Camera {
            right: turn(c.right),
            up: turn(c.up),
            forward: turn(c.forward),
        },
        ..*frame
    }
}

/// One entity as it is ray-cast: in its own axes, where its quadric and its clip are
/// axis-aligned. An oriented entity is an axis-aligned one there, drawn with the camera and
/// its centre turned by `R^T` instead of the entity by `R`.
struct Placed<'a> {
    frame: Frame,
    /// Centre, local to the frame's origin, turned.
    c: [f64; 3],
    /// `w_j = 1 / r_j^2`, 0 on an infinite axis.
    w: [f64; 3],
    r: [f64; 3],
    clip: &'a Clip,
}

impl<'a> Placed<'a> {
    fn new(frame: &Frame, shift: [f64; 3], e: &mema_core::MapEntity, clip: &'a Clip) -> Self {
        let rotation = e.entity.rotation;
        let c = rotation
            .inverse_rotate([0, 1, 2].map(|j| f64::from(e.entity.center.to_array()[j]) + shift[j]));
        Placed {
            frame: in_entity_axes(frame, &rotation),
            c,
            w: e.entity.weights.map(f64::from),
            r: e.entity.semi_axes().map(f64::from),
            clip,
        }
    }

    /// The range of `p · d` over the entity (its infinite axes cut by the clip), `d` in its
    /// axes: the support function of an ellipsoid plus a box.
    fn support(&self, d: [f64; 3]) -> [f64; 2] {
        let (mut mid, mut ellipse, mut lo, mut hi) = (0.0, 0.0, 0.0, 0.0);
        for (j, d) in d.into_iter().enumerate() {
            if self.r[j].is_finite() {
                mid += self.c[j] * d;
                ellipse += (self.r[j] * d).powi(2);
            } else {
                let (a, b) = (self.clip.0[j] * d, self.clip.1[j] * d);
                lo += a.min(b);
                hi += a.max(b);
            }
        }
        let half = ellipse.sqrt();
        [mid - half + lo, mid + half + hi]
    }

    /// What of the screen plane the entity covers (see [`Extent`]).
    fn extent(&self) -> Extent {
        let cam = self.frame.camera;
        let (s, t) = (self.support(cam.right), self.support(cam.up));
        let mut e = Extent::EMPTY;
        e.include(s[0], t[0]);
        e.include(s[1], t[1]);
        e
    }

    /// The pixel columns of row `y` whose centres the silhouette may cover, within `xs`:
    /// the interval where the ray's closest approach to the quadric's centre lies inside it,
    /// `A x^2 + 2 B x + C <= 1` in the pixel column `x`, widened by a pixel each side so
    /// rounding never loses a pixel that [`hit`] finds. The clip only removes pixels,
    /// so the quadric's interval holds the clipped entity's.
    fn row_span(&self, y: i64, xs: &std::ops::Range<i64>) -> std::ops::Range<i64> {
        let (f, w) = (self.frame.camera.forward, self.w);
        let a: f64 = (0..3).map(|j| w[j] * f[j] * f[j]).sum();
        // Minimising over the ray's depth leaves the form M = W - (W f)(W f)^T / a; a ray
        // along an infinite axis (a = 0) must start inside, M = W.
        let m = |u: [f64; 3], v: [f64; 3]| -> f64 {
            let q: f64 = (0..3).map(|j| w[j] * u[j] * v[j]).sum();
            if a > 1e-12 {
                let (uf, vf): (f64, f64) = (
                    (0..3).map(|j| w[j] * u[j] * f[j]).sum(),
                    (0..3).map(|j| w[j] * v[j] * f[j]).sum(),
                );
                q - uf * vf / a
            } else {
                q
            }
        };
        // The ray through pixel x's centre starts at o(x) = g + x step from the centre.
        let centre_y = y as f64 + 0.5;
        let (start, next) = (
            self.frame.unproject(0.5, centre_y),
            self.frame.unproject(1.5, centre_y),
        );
        let g = [0, 1, 2].map(|j| start[j] - self.c[j]);
        let step = [0, 1, 2].map(|j| next[j] - start[j]);
        let (aa, bb, cc) = (m(step, step), m(step, g), m(g, g) - 1.0);
        if aa <= 1e-300 || !(aa.is_finite() && bb.is_finite() && cc.is_finite()) {
            return xs.clone();
        }
        let disc = bb * bb - aa * cc;
        if disc < -1e-7 * (bb * bb + (aa * cc).abs()) {
            return 0..0;
        }
        let root = disc.max(0.0).sqrt();
        let (s0, s1) = ((-bb - root) / aa, (-bb + root) / aa);
        // Pixel x is hit where s0 <= x <= s1; one more each side absorbs the rounding.
        let from = (s0.ceil() as i64).saturating_sub(1).max(xs.start);
        let to = (s1.floor() as i64).saturating_add(2).min(xs.end);
        from..to.max(from)
    }
}

/// What the entities of `map` cover on the screen plane of `frame` (its scale and offset
/// aside), their infinite axes cut by `clips`: [`Frame::fit_extent`] fits a picture to it.
pub fn entities_extent(frame: &Frame, map: &HostMap, clips: &[Clip]) -> Extent {
    let shift = [0, 1, 2].map(|j| map.origin[j] - frame.origin[j]);
    let mut extent = Extent::EMPTY;
    for (e, clip) in map.entities.iter().zip(clips) {
        extent.union(&Placed::new(frame, shift, e, clip).extent());
    }
    extent
}

/// The work of drawing entities: the rows their silhouettes' boxes span, the rays cast (one
/// per pixel visited) and the rays that hit. Spans keep `rays` within a few pixels a row of
/// `hits`, where whole boxes cast a ray for every pixel of each box.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DrawCost {
    pub entities: u64,
    pub rows: u64,
    pub rays: u64,
    pub hits: u64,
}

/// Renders `map`'s entities into `plot` of `raster`; `clips[i]` bounds entity i's infinite
/// axes, in its own axes (see [`Clip`]).
pub fn draw_entities(
    raster: &mut Raster,
    frame: &Frame,
    map: &HostMap,
    clips: &[Clip],
    plot: [u32; 4],
    style: Style,
) -> DrawCost {
    draw_entities_counted(raster, frame, map, clips, plot, style, &|| {})
}

/// [`draw_entities`], calling `done` after each entity (a progress bar's step).
pub fn draw_entities_counted(
    raster: &mut Raster,
    frame: &Frame,
    map: &HostMap,
    clips: &[Clip],
    plot: [u32; 4],
    style: Style,
    done: &dyn Fn(),
) -> DrawCost {
    paint_entities(raster, frame, map, clips, plot, style, Cull::Rows, done)
}

/// Which pixels an entity visits: its projected box's, or only the spans its rows may cover.
/// Both paint the same pixels; the box is kept as the reference the spans are tested against.
#[derive(Clone, Copy, PartialEq)]
enum Cull {
    Rows,
    #[cfg_attr(not(test), allow(dead_code))]
    Box,
}

#[allow(clippy::too_many_arguments)]
fn paint_entities(
    raster: &mut Raster,
    frame: &Frame,
    map: &HostMap,
    clips: &[Clip],
    plot: [u32; 4],
    style: Style,
    cull: Cull,
    done: &dyn Fn(),
) -> DrawCost {
    let mut cost = DrawCost::default();
    let shift = [0, 1, 2].map(|j| map.origin[j] - frame.origin[j]);
    let toward_light = {
        let cam = frame.camera;
        let l = [0, 1, 2].map(|j| -cam.forward[j] + 0.6 * cam.up[j] - 0.4 * cam.right[j]);
        let n = dot(l, l).sqrt();
        l.map(|v| v / n)
    };
    let [px, py, pw, ph] = plot.map(i64::from);
    for (e, clip) in map.entities.iter().zip(clips) {
        let placed = Placed::new(frame, shift, e, clip);
        let (frame, c, w) = (placed.frame, placed.c, placed.w);
        let cam = frame.camera;
        let toward_light = e.entity.rotation.inverse_rotate(toward_light);
        // The silhouette's screen box bounds its pixels.
        let extent = placed.extent();
        let (x0, x1) = (
            frame.offset[0] + frame.scale * extent.s[0],
            frame.offset[0] + frame.scale * extent.s[1],
        );
        let (y0, y1) = (
            frame.offset[1] - frame.scale * extent.t[1],
            frame.offset[1] - frame.scale * extent.t[0],
        );
        let xs = (x0.floor() as i64).max(px)..(x1.ceil() as i64).saturating_add(1).min(px + pw);
        let ys = (y0.floor() as i64).max(py)..(y1.ceil() as i64).saturating_add(1).min(py + ph);
        let colour = kind_colour(e.kind);
        let covered = |x: i64, y: i64| {
            let p = frame.unproject(x as f64 + 0.5, y as f64 + 0.5);
            hit(p, cam.forward, c, w, clip)
        };
        cost.entities += 1;
        for y in ys {
            let span = match cull {
                Cull::Rows => placed.row_span(y, &xs),
                Cull::Box => xs.clone(),
            };
            cost.rows += 1;
            cost.rays += span.end.saturating_sub(span.start).max(0) as u64;
            for x in span {
                let Some((t, n)) = covered(x, y) else {
                    continue;
                };
                cost.hits += 1;
                match style {
                    Style::Shaded => {
                        let len = dot(n, n).sqrt().max(1e-300);
                        let lambert = (dot(n, toward_light) / len).abs();
                        let shade = AMBIENT + (1.0 - AMBIENT) * lambert;
                        raster.put_nearer(
                            x,
                            y,
                            t,
                            colour.map(|v| (f64::from(v) * shade).round() as u8),
                        );
                    }
                    Style::Outline => {
                        let edge = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                            .iter()
                            .any(|(dx, dy)| covered(x + dx, y + dy).is_none());
                        if edge {
                            raster.put(x, y, colour);
                        }
                    }
                }
            }
        }
        done();
    }
    cost
}

/// Dots of `size` pixels at the points' projections, behind any nearer entity surface.
pub fn draw_points(
    raster: &mut Raster,
    frame: &Frame,
    points: &[[f64; 3]],
    size: i64,
    depth_test: bool,
) {
    for p in points {
        let (x, y, t) = frame.project(*p);
        let (x, y) = (x.floor() as i64, y.floor() as i64);
        for dy in 0..size {
            for dx in 0..size {
                if depth_test {
                    raster.put_nearer(x + dx, y + dy, t, POINT_COLOUR);
                } else {
                    raster.put(x + dx, y + dy, POINT_COLOUR);
                }
            }
        }
    }
}

/// The longest 1, 2 or 5 times a power of ten that is at most `limit`.
pub fn nice_length(limit: f64) -> f64 {
    let p = 10f64.powf(limit.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|&l| l <= limit)
        .unwrap_or(p)
}

/// A legend entry as drawn: the swatch rectangle is [x, y, w, h] in pixels.
#[derive(Clone, Debug, Serialize)]
pub struct LegendEntry {
    pub kind: &'static str,
    pub count: usize,
    pub colour: [u8; 3],
    pub swatch: [i64; 4],
}

/// Draws the legend (kinds present, with counts) from (x, y) downwards.
pub fn draw_legend(
    raster: &mut Raster,
    x: i64,
    y: i64,
    ts: i64,
    map: &HostMap,
    points: usize,
) -> Vec<LegendEntry> {
    let mut entries = Vec::new();
    let row = 10 * ts;
    let mut yy = y;
    for kind in EntityKind::ALL {
        let count = map.entities.iter().filter(|e| e.kind == kind).count();
        if count == 0 {
            continue;
        }
        let swatch = [x, yy, 8 * ts, 8 * ts];
        raster.fill(swatch, kind_colour(kind));
        raster.text(
            x + 10 * ts,
            yy,
            ts,
            &format!("{} {count}", kind.name()),
            INK,
        );
        entries.push(LegendEntry {
            kind: kind.name(),
            count,
            colour: kind_colour(kind),
            swatch,
        });
        yy += row;
    }
    raster.fill([x + 3 * ts, yy + 3 * ts, 2 * ts, 2 * ts], POINT_COLOUR);
    raster.text(x + 10 * ts, yy, ts, &format!("points {points}"), INK);
    entries
}

/// A length in metres as a scale bar labels it: in the largest of km, m, cm, mm and um that
/// leaves at least 1 of it ("10 cm", "1 m", "2 km"), to three significant digits.
pub fn length_label(metres: f64) -> String {
    let units = [
        (1e3, "km"),
        (1.0, "m"),
        (1e-2, "cm"),
        (1e-3, "mm"),
        (1e-6, "um"),
    ];
    let (size, name) = units
        .into_iter()
        .find(|(size, _)| metres >= *size * (1.0 - 1e-9))
        .unwrap_or((1e-6, "um"));
    let value = metres / size;
    // Three significant digits drop the powf's last-bit noise (0.05 / 0.01 = 5.000000000000001).
    let digits = (2 - value.abs().max(1e-300).log10().floor() as i32).max(0) as usize;
    let text = format!("{value:.digits$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        &text
    };
    format!("{text} {name}")
}

/// The scale bar as drawn: its length in metres, its pixels and its label.
#[derive(Clone, Debug, Serialize)]
pub struct ScaleBar {
    /// In metres (the cloud is read in metres).
    pub length: f64,
    pub pixels: i64,
    /// The length with its unit, as drawn ("10 cm").
    pub label: String,
}

/// A bar of a round length ending at (right, y), labelled with its unit.
pub fn draw_scale_bar(
    raster: &mut Raster,
    right: i64,
    y: i64,
    ts: i64,
    frame: &Frame,
    max_pixels: f64,
) -> ScaleBar {
    let length = nice_length(max_pixels / frame.scale);
    let pixels = (length * frame.scale).round() as i64;
    let x0 = right - pixels;
    raster.fill([x0, y, pixels, 2 * ts], INK);
    raster.fill([x0, y - 2 * ts, ts, 6 * ts], INK);
    raster.fill([right - ts, y - 2 * ts, ts, 6 * ts], INK);
    let label = length_label(length);
    let width = 8 * ts * label.chars().count() as i64;
    raster.text(x0 + (pixels - width) / 2, y + 4 * ts, ts, &label, INK);
    ScaleBar {
        length,
        pixels,
        label,
    }
}

/// What one panel shows, apart from its map.
pub struct PanelScene<'a> {
    pub frame: Frame,
    /// Per entity: where its infinite axes end, local to the frame's origin.
    pub clips: Vec<Clip>,
    pub plot: [u32; 4],
    pub style: Style,
    pub points: &'a [[f64; 3]],
    pub point_size: i64,
}

/// Shaded: solids, then the points that lie in front of them. Outline: points, then outlines.
/// `done` is called after each entity.
pub fn draw_panel(
    raster: &mut Raster,
    scene: &PanelScene,
    map: &HostMap,
    done: &dyn Fn(),
) -> DrawCost {
    let s = scene;
    let entities = |raster: &mut Raster, style| {
        draw_entities_counted(raster, &s.frame, map, &s.clips, s.plot, style, done)
    };
    match s.style {
        Style::Shaded => {
            let cost = entities(raster, Style::Shaded);
            draw_points(raster, &s.frame, s.points, s.point_size, true);
            cost
        }
        Style::Outline => {
            draw_points(raster, &s.frame, s.points, s.point_size, false);
            entities(raster, Style::Outline)
        }
    }
}

#[cfg(test)]
mod tests;
