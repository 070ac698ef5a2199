//! Every PNG chart of the project, on plotters: line charts of named series ([`lines`]), latency
//! histograms ([`latency`]), the lap trace ([`trace`]), the experiments' per-variant dot plots
//! ([`dots`]) and the figure strip's labelled image grid ([`grid`]).
//!
//! Text is drawn with DejaVu Sans, shipped in `tools/plot/fonts/` with its licence and compiled in, so
//! no system font is needed at run time. plotters draws into an RGB buffer that `png` encodes:
//! no `image` crate. No libtorch, MuJoCo or iceoryx2 here.

pub mod dots;
pub mod grid;
pub mod latency;
mod legend;
pub mod lines;
pub mod pairs;
pub mod ticks;
pub mod trace;

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

pub use dots::variants_dot_plot;
pub use grid::{Cell, image_grid};
pub use latency::latency_histograms;
pub use lines::{Panel, Series, category_chart, lines_chart};
pub use pairs::{Pair, pairs_chart};
pub use trace::{Path2d, lap_trace};

pub type Rgb = [u8; 3];

pub const BLUE: Rgb = [0, 110, 220];
pub const ORANGE: Rgb = [240, 150, 0];
pub const RED: Rgb = [210, 40, 40];
pub const GREEN: Rgb = [20, 150, 60];
pub const PURPLE: Rgb = [140, 0, 160];
pub const GREY: Rgb = [170, 170, 170];
pub const BLACK: Rgb = [0, 0, 0];

/// One font for all text; plotters asks for "sans-serif" unless told otherwise.
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// Why a chart could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters failed while drawing (a value it could not place, a font it could not use).
    #[error("drawing {path}: {detail}")]
    Draw { path: PathBuf, detail: String },
    /// The PNG could not be encoded or written.
    #[error("writing {path}: {detail}")]
    Write { path: PathBuf, detail: String },
}

pub(crate) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
pub(crate) type DrawResult = Result<(), Box<dyn std::error::Error>>;

pub(crate) fn colour(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Text of `size` px in the shipped font.
pub(crate) fn text(size: u32) -> TextStyle<'static> {
    register_font();
    (FAMILY, size as f64).into_font().into()
}

/// Once per process: plotters' ab_glyph text knows only the fonts registered with it.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are ours and known to parse (every chart's test draws text).
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// Draws into a white `width` x `height` RGB picture with `draw` and writes it to `path`.
pub(crate) fn render(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(&Area) -> DrawResult,
) -> Result<(), PlotError> {
    register_font();
    let mut px = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut px, (width, height)).into_drawing_area();
        let drawn = draw(&root).and_then(|()| root.present().map_err(Into::into));
        drawn.map_err(|e| PlotError::Draw {
            path: path.to_owned(),
            detail: e.to_string(),
        })?;
    }
    write_png(path, (width, height), &px)
}

fn write_png(path: &Path, (width, height): (u32, u32), px: &[u8]) -> Result<(), PlotError> {
    let err = |e: &dyn std::fmt::Display| PlotError::Write {
        path: path.to_owned(),
        detail: e.to_string(),
    };
    let file = std::fs::File::create(path).map_err(|e| err(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| err(&e))?;
    w.write_image_data(px).map_err(|e| err(&e))?;
    w.finish().map_err(|e| err(&e))
}

/// What a PNG shows, for tests here and in other crates: a chart's test counts the pixels of
/// the colours it drew with (a blank or axes-only picture has none beyond the legend's swatch,
/// at most 17 x 13 pixels).
pub mod test_png {
    use std::path::Path;

    /// The PNG's size and its RGB pixels.
    pub fn decode(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
        let file = std::fs::File::open(path).unwrap();
        let mut r = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        let px = buf[..info.buffer_size()]
            .chunks(3)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        (info.width, info.height, px)
    }

    /// Pixels within 40 of `colour` on every channel (antialiased edges blend).
    pub fn near(px: &[[u8; 3]], colour: [u8; 3]) -> usize {
        px.iter()
            .filter(|p| (0..3).all(|i| p[i].abs_diff(colour[i]) <= 40))
            .count()
    }

    /// Pixels that are not white.
    pub fn inked(px: &[[u8; 3]]) -> usize {
        px.iter().filter(|p| **p != [255, 255, 255]).count()
    }
}
