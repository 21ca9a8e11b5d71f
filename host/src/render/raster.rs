//! The picture `mema draw` paints: RGB pixels with a depth buffer, text from the `font8x8`
//! bitmap font compiled into the binary (so drawing needs no font file and cannot fail for want
//! of one), and PNG encoding. Every pixel goes through [`Raster::put`], which drops anything
//! outside the picture.

/// The picture's background.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];

/// A lowercase m with three legs. font8x8's is a small capital M (rows 3 and 4 solid), which
/// reads as a blot at the scale bar's size, where "m" and "cm" matter. Bit `c` of row `r` is
/// the pixel in column `c`, as in font8x8.
const LOWERCASE_M: [u8; 8] = [
    0b0000_0000,
    0b0000_0000,
    0b0011_0111,
    0b0110_1011,
    0b0110_1011,
    0b0110_1011,
    0b0110_1011,
    0b0000_0000,
];

/// The 8x8 glyph of `ch`; characters outside the font are blank.
pub fn glyph(ch: char) -> [u8; 8] {
    use font8x8::UnicodeFonts;
    match ch {
        'm' => LOWERCASE_M,
        _ => font8x8::BASIC_FONTS.get(ch).unwrap_or([0; 8]),
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
    pub(crate) fn put_nearer(&mut self, x: i64, y: i64, depth: f64, colour: [u8; 3]) {
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

    /// 8x8 glyphs ([`glyph`]) scaled by `scale`.
    pub fn text(&mut self, x: i64, y: i64, scale: i64, s: &str, colour: [u8; 3]) {
        for (n, ch) in s.chars().enumerate() {
            let gx = x + 8 * scale * n as i64;
            for (row, bits) in glyph(ch).iter().enumerate() {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of set pixels in one glyph row.
    fn runs(bits: u8) -> usize {
        (0..8)
            .filter(|&c| bits >> c & 1 == 1 && (c == 0 || bits >> (c - 1) & 1 == 0))
            .count()
    }

    /// The m drawn is a lowercase m: three legs down to its baseline, an open top (no row
    /// solid across), shorter than the capitals, and unlike the M beside it.
    #[test]
    fn the_lowercase_m_has_three_legs_and_no_solid_row() {
        let m = glyph('m');
        let inked: Vec<usize> = (0..8).filter(|&r| m[r] != 0).collect();
        let (top, bottom) = (inked[0], inked[inked.len() - 1]);
        assert!(top > 0, "a lowercase letter starts below the capitals' top");
        for (row, bits) in m.iter().enumerate().take(bottom + 1).skip(top + 1) {
            assert_eq!(runs(*bits), 3, "row {row}: {bits:08b}");
        }
        assert!(m.iter().all(|&r| r.count_ones() < 6), "{m:?}");
        assert_ne!(m, glyph('M'));
        // Drawn, it is the glyph: three legs on its baseline.
        let mut r = Raster::new(8, 8);
        r.text(0, 0, 1, "m", [0, 0, 0]);
        let row: u8 = (0..8)
            .filter(|&c| r.pixels[bottom * 8 + c] != BACKGROUND)
            .map(|c| 1u8 << c)
            .sum();
        assert_eq!(runs(row), 3);
    }
}
