//! A small RGB raster for the run's pictures (lap trace, latency histogram, curves): points,
//! lines, boxes and font8x8 labels, written as PNG. No system fonts, no plotting dependency;
//! the model's figure strip draws its labels with the same glyphs ([`glyph_pixels`]).

use std::path::Path;

use anyhow::Context;

pub type Rgb = [u8; 3];

pub const BLACK: Rgb = [0, 0, 0];
pub const GREY: Rgb = [190, 190, 190];

pub struct Canvas {
    pub width: usize,
    pub height: usize,
    px: Vec<u8>,
}

impl Canvas {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            px: vec![255; width * height * 3],
        }
    }

    pub fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = (y as usize * self.width + x as usize) * 3;
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    /// A filled square of side `2r + 1` around (x, y).
    pub fn dot(&mut self, x: i64, y: i64, r: i64, c: Rgb) {
        for dy in -r..=r {
            for dx in -r..=r {
                self.set(x + dx, y + dy, c);
            }
        }
    }

    pub fn line(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: Rgb) {
        let n = (x1 - x0).abs().max((y1 - y0).abs()).max(1);
        for k in 0..=n {
            let x = x0 + (x1 - x0) * k / n;
            let y = y0 + (y1 - y0) * k / n;
            self.set(x, y, c);
        }
    }

    pub fn rect(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: Rgb) {
        for y in y0.min(y1)..=y0.max(y1) {
            for x in x0.min(x1)..=x0.max(x1) {
                self.set(x, y, c);
            }
        }
    }

    /// ASCII text, 8 px glyphs scaled by `scale`, top-left at (x, y).
    pub fn text(&mut self, x: i64, y: i64, text: &str, scale: i64, c: Rgb) {
        for (dx, dy) in glyph_pixels(text, scale.max(1) as usize) {
            self.set(x + dx as i64, y + dy as i64, c);
        }
    }

    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let file =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut enc = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header()?;
        w.write_image_data(&self.px)?;
        w.finish()?;
        Ok(())
    }
}

/// The pixels `(x, y)` of ASCII `text` in font8x8 glyphs scaled by `scale`, from the text's
/// top-left corner; other characters draw as blanks.
pub fn glyph_pixels(text: &str, scale: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
    text.chars().enumerate().flat_map(move |(i, ch)| {
        let glyph = font8x8::legacy::BASIC_LEGACY
            .get(ch as usize)
            .copied()
            .unwrap_or_default();
        (0..8usize).flat_map(move |gy| {
            (0..8usize)
                .filter(move |gx| glyph[gy] & (1 << gx) != 0)
                .flat_map(move |gx| {
                    (0..scale * scale)
                        .map(move |k| ((i * 8 + gx) * scale + k % scale, gy * scale + k / scale))
                })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_and_writes_a_png() {
        let mut c = Canvas::new(40, 20);
        c.line((0, 0), (39, 19), BLACK);
        c.text(2, 2, "Hi", 1, [200, 0, 0]);
        c.dot(100, 100, 2, BLACK); // off the canvas: ignored
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.png");
        c.write(&p).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert_eq!(&c.px[0..3], &BLACK, "the line starts at the corner");
    }
}
