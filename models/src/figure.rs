//! The paper's Figs 3-7 as one grayscale PNG strip: a column per chosen frame; rows: original
//! frame, predicted frame, then the first generative unit's output h of each layer, with row
//! and frame labels.

use crate::model::{ModelError, MtaPredNet};
use mtanet_canvas::glyph_pixels;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tch::{Kind, Tensor};

/// The paper's frames.
pub const DEFAULT_FRAMES: [usize; 5] = [1, 10, 50, 100, 130];
/// Each pixel of the input image becomes SCALE x SCALE; deeper layers are stretched to match.
const SCALE: usize = 8;
const GAP: usize = 3;
/// Labels are font8x8 glyphs drawn at TEXT_SCALE (16 px characters).
const TEXT_SCALE: usize = 2;
const GLYPH: usize = 8 * TEXT_SCALE;

/// What the strip shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FigureInfo {
    /// Frames drawn, left to right.
    pub frames: Vec<usize>,
    /// Requested frames past the end of the sequence (left out).
    pub frames_missing: Vec<usize>,
    /// Row labels, top to bottom.
    pub rows: Vec<String>,
    /// Per layer, the channel of GU 0 drawn: the one that varies most over the sequence.
    pub channels: Vec<i64>,
}

/// Why the figure could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// The sequence does not fit the model.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// None of the requested frames exists in the sequence.
    #[error("no requested frame {requested:?} exists in a sequence of {steps} steps")]
    NoFrames { requested: Vec<usize>, steps: i64 },
    /// Inputs are not one sequence (`[T, H, W]` images, `[T, A]` actions).
    #[error(
        "expected one sequence: images [T, H, W] and actions [T, A], got {images:?} and {actions:?}"
    )]
    Shape { images: Vec<i64>, actions: Vec<i64> },
    /// The PNG could not be written.
    #[error("{path}: {detail}")]
    Write { path: PathBuf, detail: String },
}

/// Runs `model` over one sequence and draws the strip at `frames` into `path` (PNG). Frames past
/// the end are left out and listed in the returned info.
pub fn figure_strip(
    model: &MtaPredNet,
    images: &Tensor,
    actions: &Tensor,
    frames: &[usize],
    path: &Path,
) -> Result<FigureInfo, FigureError> {
    let (is, as_) = (images.size(), actions.size());
    if is.len() != 3 || as_.len() != 2 || is[0] != as_[0] {
        return Err(FigureError::Shape {
            images: is,
            actions: as_,
        });
    }
    let steps = is[0];
    let (used, missing): (Vec<usize>, Vec<usize>) =
        frames.iter().partition(|&&f| (f as i64) < steps);
    if used.is_empty() {
        return Err(FigureError::NoFrames {
            requested: frames.to_vec(),
            steps,
        });
    }
    let _g = tch::no_grad_guard();
    let layers = model.layers.len();
    let mut preds = Vec::new();
    let mut gu0: Vec<Vec<Tensor>> = (0..layers).map(|_| Vec::new()).collect(); // per layer, [C, H_l, W_l] per t
    let mut state = model.zero_state(1);
    let w = model.inference_weights();
    for t in 0..steps {
        let (next, out) = model.f_step_with(
            &w,
            &state,
            &images.get(t).unsqueeze(0),
            &actions.get(t).unsqueeze(0),
        )?;
        preds.push(out.prediction.view([is[1], is[2]]));
        for (l, ls) in next.layers.iter().enumerate() {
            gu0[l].push(ls.h.get(0).get(0));
        }
        state = next;
    }
    let mut rows: Vec<Vec<Tensor>> = vec![
        used.iter()
            .map(|&f| images.get(f as i64).clamp(0.0, 1.0))
            .collect(),
        used.iter().map(|&f| preds[f].clamp(0.0, 1.0)).collect(),
    ];
    let mut channels = Vec::new();
    for seq in &gu0 {
        let all = Tensor::stack(seq, 0); // [T, C, H, W]
        let c = all
            .var_dim([0, 2, 3].as_slice(), false, false)
            .argmax(0, false)
            .int64_value(&[]);
        channels.push(c);
        // One min-max range per row so that the columns are comparable.
        let picked: Vec<Tensor> = used.iter().map(|&f| all.get(f as i64).get(c)).collect();
        let lo = Tensor::stack(&picked, 0).min().double_value(&[]);
        let hi = Tensor::stack(&picked, 0).max().double_value(&[]);
        let span = (hi - lo).max(1e-9);
        rows.push(picked.iter().map(|p| (p - lo) / span).collect());
    }
    let mut row_labels = vec!["input".to_string(), "predicted".to_string()];
    row_labels.extend((0..layers).map(|l| format!("L{l} GU0")));
    let col_labels: Vec<String> = used.iter().map(|f| format!("t={f}")).collect();
    let strip = Strip {
        rows: &rows,
        row_labels: &row_labels,
        col_labels: &col_labels,
    };
    strip.write(path, (is[1] as usize, is[2] as usize))?;
    let mut labels = vec![
        "original X_0(t)".to_string(),
        "predicted Xhat_0(t)".to_string(),
    ];
    labels.extend((0..layers).map(|l| format!("layer {l} GU 0 h, channel {}", channels[l])));
    Ok(FigureInfo {
        frames: used,
        frames_missing: missing,
        rows: labels,
        channels,
    })
}

/// Cells in a grid with a label left of each row and above each column.
struct Strip<'a> {
    /// 2-d tensors in [0, 1], `rows[r][c]`.
    rows: &'a [Vec<Tensor>],
    row_labels: &'a [String],
    col_labels: &'a [String],
}

impl Strip<'_> {
    /// Draws the cells at the image's size x SCALE, separated by white gaps (smaller maps are
    /// stretched, nearest), labels in black, and writes a grayscale PNG.
    fn write(&self, path: &Path, (h, w): (usize, usize)) -> Result<(), FigureError> {
        let (ch, cw) = (h * SCALE, w * SCALE);
        let cols = self.rows.first().map_or(0, Vec::len);
        let longest = self.row_labels.iter().map(String::len).max().unwrap_or(0);
        let (left, top) = (longest * GLYPH + 2 * GAP, GLYPH + 2 * GAP);
        let width = left + cols * cw + (cols + 1) * GAP;
        let height = top + self.rows.len() * ch + (self.rows.len() + 1) * GAP;
        let mut px = vec![255u8; width * height];
        let cell_origin =
            |r: usize, c: usize| (top + GAP + r * (ch + GAP), left + GAP + c * (cw + GAP));
        for (r, row) in self.rows.iter().enumerate() {
            for (c, cell) in row.iter().enumerate() {
                let cell = cell.unsqueeze(0).unsqueeze(0).to_kind(Kind::Float);
                let big = cell
                    .upsample_nearest2d([ch as i64, cw as i64], None, None)
                    .flatten(0, -1);
                let vals = Vec::<f32>::try_from(big).map_err(|e| write_err(path, e))?;
                let (y0, x0) = cell_origin(r, c);
                for y in 0..ch {
                    for x in 0..cw {
                        px[(y0 + y) * width + x0 + x] =
                            (vals[y * cw + x].clamp(0.0, 1.0) * 255.0).round() as u8;
                    }
                }
            }
        }
        for (r, label) in self.row_labels.iter().enumerate() {
            let (y0, _) = cell_origin(r, 0);
            draw_text(&mut px, width, (y0 + (ch - GLYPH) / 2, GAP), label);
        }
        for (c, label) in self.col_labels.iter().enumerate() {
            let (_, x0) = cell_origin(0, c);
            draw_text(&mut px, width, (GAP, x0), label);
        }
        let file = std::fs::File::create(path).map_err(|e| write_err(path, e))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(|e| write_err(path, e))?;
        writer
            .write_image_data(&px)
            .map_err(|e| write_err(path, e))?;
        writer.finish().map_err(|e| write_err(path, e))
    }
}

/// Black ASCII text with its top-left corner at `(y, x)`.
fn draw_text(px: &mut [u8], width: usize, (y, x): (usize, usize), text: &str) {
    for (dx, dy) in glyph_pixels(text, TEXT_SCALE) {
        let (py, pxx) = (y + dy, x + dx);
        if let Some(p) = px.get_mut(py * width + pxx).filter(|_| pxx < width) {
            *p = 0;
        }
    }
}

fn write_err(path: &Path, e: impl ToString) -> FigureError {
    FigureError::Write {
        path: path.to_owned(),
        detail: e.to_string(),
    }
}
