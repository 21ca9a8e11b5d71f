//! `mema draw`: a headless orthographic render of a cloud and its map(s) into an RGB raster.
//!
//! Entities are ray-cast per pixel (exact silhouettes and depths, no tessellation), points are
//! depth-tested dots drawn over them, and text comes from the `font8x8` bitmap font compiled
//! into the binary, so drawing needs no font file and cannot fail for want of one. Rendering
//! touches pixels through `Raster::put`, which drops anything outside the picture.
//!
//! The projection is the contract the tests use: with `p` a world point, `o` the frame's
//! origin, pixel column `x = offset[0] + scale ((p - o) · right)` and row
//! `y = offset[1] - scale ((p - o) · up)`; pixel (i, j) covers `[i, i+1) x [j, j+1)`.

use mema_core::{EntityKind, Rotation};
use serde::Serialize;

use super::export::kind_colour;
use crate::io::mapfile::HostMap;

/// The picture's background.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
/// The cloud's points.
pub const POINT_COLOUR: [u8; 3] = [25, 25, 25];
/// Text and scale bar.
pub const INK: [u8; 3] = [0, 0, 0];
/// Diffuse shading spans `[AMBIENT, 1]` times the kind's colour.
pub const AMBIENT: f64 = 0.35;

/// The direction a picture looks along.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum View {
    /// Along (-1, 1, -1): x and y recede to the right and left, z up.
    Iso,
    /// Down the z axis: x right, y up.
    Top,
    /// Along +y: x right, z up.
    Front,
    /// Along -x: y right, z up.
    Side,
}

/// How entities are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Style {
    /// Lambert-shaded solids in the kind's colour.
    Shaded,
    /// Silhouettes only, over the points.
    Outline,
}

/// An orthographic camera: unit screen axes and the viewing direction (into the screen).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Camera {
    pub right: [f64; 3],
    pub up: [f64; 3],
    pub forward: [f64; 3],
}

impl View {
    /// The view's name, as `--json` and the command line spell it.
    pub fn name(self) -> &'static str {
        match self {
            View::Iso => "iso",
            View::Top => "top",
            View::Front => "front",
            View::Side => "side",
        }
    }

    /// The view's orthographic camera.
    pub fn camera(self) -> Camera {
        let (s2, s3, s6) = (2f64.sqrt(), 3f64.sqrt(), 6f64.sqrt());
        match self {
            View::Top => Camera {
                right: [1., 0., 0.],
                up: [0., 1., 0.],
                forward: [0., 0., -1.],
            },
            View::Front => Camera {
                right: [1., 0., 0.],
                up: [0., 0., 1.],
                forward: [0., 1., 0.],
            },
            View::Side => Camera {
                right: [0., 1., 0.],
                up: [0., 0., 1.],
                forward: [-1., 0., 0.],
            },
            View::Iso => Camera {
                right: [1. / s2, 1. / s2, 0.],
                up: [-1. / s6, 1. / s6, 2. / s6],
                forward: [-1. / s3, 1. / s3, -1. / s3],
            },
        }
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// World to pixel for one panel (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Frame {
    pub origin: [f64; 3],
    #[serde(flatten)]
    pub camera: Camera,
    /// Pixels per cloud unit.
    pub scale: f64,
    pub offset: [f64; 2],
}

impl Frame {
    /// Fits the projections of `points` (local to `origin`) into `plot` = [x, y, w, h].
    pub fn fit(origin: [f64; 3], camera: Camera, points: &[[f64; 3]], plot: [u32; 4]) -> Self {
        let (mut s0, mut s1, mut t0, mut t1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in points {
            let (s, t) = (dot(*p, camera.right), dot(*p, camera.up));
            (s0, s1, t0, t1) = (s0.min(s), s1.max(s), t0.min(t), t1.max(t));
        }
        let [x, y, w, h] = plot.map(f64::from);
        let scale = (w / (s1 - s0).max(1e-12)).min(h / (t1 - t0).max(1e-12));
        let offset = [
            x + w / 2.0 - scale * (s0 + s1) / 2.0,
            y + h / 2.0 + scale * (t0 + t1) / 2.0,
        ];
        Frame {
            origin,
            camera,
            scale,
            offset,
        }
    }

    /// Pixel coordinates and depth of a point local to the frame's origin.
    pub fn project(&self, p: [f64; 3]) -> (f64, f64, f64) {
        let c = &self.camera;
        let x = self.offset[0] + self.scale * dot(p, c.right);
        let y = self.offset[1] - self.scale * dot(p, c.up);
        (x, y, dot(p, c.forward))
    }

    /// The local point on the screen plane (depth 0) under pixel coordinates (x, y).
    fn unproject(&self, x: f64, y: f64) -> [f64; 3] {
        let (s, t) = (
            (x - self.offset[0]) / self.scale,
            (self.offset[1] - y) / self.scale,
        );
        let c = &self.camera;
        [0, 1, 2].map(|j| s * c.right[j] + t * c.up[j])
    }
}

/// An RGB picture with a depth buffer.
pub struct Raster {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
    depth: Vec<f64>,
}

impl Raster {
    /// A picture of the background colour.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Raster {
            width,
            height,
            pixels: vec![BACKGROUND; n],
            depth: vec![f64::INFINITY; n],
        }
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        let inside = (0..self.width as i64).contains(&x) && (0..self.height as i64).contains(&y);
        inside.then(|| y as usize * self.width as usize + x as usize)
    }

    /// Sets one pixel; anything outside the picture is dropped.
    pub fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if let Some(i) = self.index(x, y) {
            self.pixels[i] = colour;
        }
    }

    /// Writes the pixel if `depth` is nearer than what is there.
    fn put_nearer(&mut self, x: i64, y: i64, depth: f64, colour: [u8; 3]) {
        if let Some(i) = self.index(x, y)
            && depth < self.depth[i]
        {
            self.depth[i] = depth;
            self.pixels[i] = colour;
        }
    }

    /// Fills the rectangle `[x, y, w, h]`, clipped to the picture.
    pub fn fill(&mut self, [x, y, w, h]: [i64; 4], colour: [u8; 3]) {
        for yy in y..y + h {
            for xx in x..x + w {
                self.put(xx, yy, colour);
            }
        }
    }

    /// 8x8 glyphs scaled by `scale`; characters outside the font are blank.
    pub fn text(&mut self, x: i64, y: i64, scale: i64, s: &str, colour: [u8; 3]) {
        use font8x8::UnicodeFonts;
        for (n, ch) in s.chars().enumerate() {
            let glyph = font8x8::BASIC_FONTS.get(ch).unwrap_or([0; 8]);
            let gx = x + 8 * scale * n as i64;
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        let (px, py) = (gx + col * scale, y + row as i64 * scale);
                        self.fill([px, py, scale, scale], colour);
                    }
                }
            }
        }
    }

    /// The picture as PNG bytes (8-bit RGB).
    pub fn encode_png(&self) -> anyhow::Result<Vec<u8>> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::High);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(self.pixels.as_flattened())?;
        writer.finish()?;
        Ok(out)
    }
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
fn in_entity_axes(frame: &Frame, rotation: &Rotation) -> Frame {
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

/// Renders `map`'s entities into `plot` of `raster`; `clips[i]` bounds entity i's infinite
/// axes, in its own axes (see [`Clip`]).
pub fn draw_entities(
    raster: &mut Raster,
    frame: &Frame,
    map: &HostMap,
    clips: &[Clip],
    plot: [u32; 4],
    style: Style,
) {
    let shift = [0, 1, 2].map(|j| map.origin[j] - frame.origin[j]);
    let toward_light = {
        let cam = frame.camera;
        let l = [0, 1, 2].map(|j| -cam.forward[j] + 0.6 * cam.up[j] - 0.4 * cam.right[j]);
        let n = dot(l, l).sqrt();
        l.map(|v| v / n)
    };
    let [px, py, pw, ph] = plot.map(i64::from);
    for (e, clip) in map.entities.iter().zip(clips) {
        // An oriented entity is an axis-aligned one in its own axes: ray-cast it there, with
        // the camera, its centre and the light turned by R^T instead of the entity by R.
        let rotation = e.entity.rotation;
        let frame = in_entity_axes(frame, &rotation);
        let cam = frame.camera;
        let toward_light = rotation.inverse_rotate(toward_light);
        let c = rotation
            .inverse_rotate([0, 1, 2].map(|j| f64::from(e.entity.center.to_array()[j]) + shift[j]));
        let w = e.entity.weights.map(f64::from);
        let r = e.entity.semi_axes().map(f64::from);
        // The entity's box in its axes (clipped where an axis is infinite), projected, bounds
        // its pixels.
        let lo = [0, 1, 2].map(|j| {
            if r[j].is_finite() {
                c[j] - r[j]
            } else {
                clip.0[j]
            }
        });
        let hi = [0, 1, 2].map(|j| {
            if r[j].is_finite() {
                c[j] + r[j]
            } else {
                clip.1[j]
            }
        });
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for corner in 0..8 {
            let q = [0, 1, 2].map(|j| if corner >> j & 1 == 0 { lo[j] } else { hi[j] });
            let (x, y, _) = frame.project(q);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        let xs = (x0.floor() as i64).max(px)..(x1.ceil() as i64 + 1).min(px + pw);
        let ys = (y0.floor() as i64).max(py)..(y1.ceil() as i64 + 1).min(py + ph);
        let colour = kind_colour(e.kind);
        let covered = |x: i64, y: i64| {
            let p = frame.unproject(x as f64 + 0.5, y as f64 + 0.5);
            hit(p, cam.forward, c, w, clip)
        };
        for y in ys.clone() {
            for x in xs.clone() {
                let Some((t, n)) = covered(x, y) else {
                    continue;
                };
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
    }
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

/// A bar of a round length ending at (right, y), labelled; returns (length, pixels).
pub fn draw_scale_bar(
    raster: &mut Raster,
    right: i64,
    y: i64,
    ts: i64,
    frame: &Frame,
    max_pixels: f64,
) -> (f64, i64) {
    let length = nice_length(max_pixels / frame.scale);
    let pixels = (length * frame.scale).round() as i64;
    let x0 = right - pixels;
    raster.fill([x0, y, pixels, 2 * ts], INK);
    raster.fill([x0, y - 2 * ts, ts, 6 * ts], INK);
    raster.fill([right - ts, y - 2 * ts, ts, 6 * ts], INK);
    let label = format!("{length}");
    let width = 8 * ts * label.len() as i64;
    raster.text(x0 + (pixels - width) / 2, y + 4 * ts, ts, &label, INK);
    (length, pixels)
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
pub fn draw_panel(raster: &mut Raster, scene: &PanelScene, map: &HostMap) {
    let s = scene;
    match s.style {
        Style::Shaded => {
            draw_entities(raster, &s.frame, map, &s.clips, s.plot, Style::Shaded);
            draw_points(raster, &s.frame, s.points, s.point_size, true);
        }
        Style::Outline => {
            draw_points(raster, &s.frame, s.points, s.point_size, false);
            draw_entities(raster, &s.frame, map, &s.clips, s.plot, Style::Outline);
        }
    }
}
