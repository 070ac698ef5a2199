//! The paper's Figs 3-7 as one PNG strip of grayscale cells: a column per chosen frame; rows: original
//! frame, predicted frame, then the first generative unit's output h of each layer, with row
//! and frame labels.

use mtanet_models::{ModelError, MtaPredNet};
use mtanet_plot::Cell;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tch::{Kind, Tensor};

/// The paper's frames.
pub const DEFAULT_FRAMES: [usize; 5] = [1, 10, 50, 100, 130];
/// Each pixel of the input image becomes SCALE x SCALE; deeper layers are stretched to match.
const SCALE: usize = 8;

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
    let layers = model.layers.len();
    let (preds, gu0) = run_sequence(model, images, actions)?;
    let mut rows: Vec<Vec<Tensor>> = vec![
        used.iter()
            .map(|&f| images.get(f as i64).clamp(0.0, 1.0))
            .collect(),
        used.iter().map(|&f| preds[f].clamp(0.0, 1.0)).collect(),
    ];
    let mut channels = Vec::new();
    for seq in &gu0 {
        let (row, c) = busiest_channel_row(seq, &used);
        channels.push(c);
        rows.push(row);
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

/// The model run over the whole sequence: its prediction at each step ([H, W]) and, per layer,
/// the first generative unit's hidden state at each step ([C, H_l, W_l]).
fn run_sequence(
    model: &MtaPredNet,
    images: &Tensor,
    actions: &Tensor,
) -> Result<(Vec<Tensor>, Vec<Vec<Tensor>>), FigureError> {
    let _g = tch::no_grad_guard();
    let is = images.size();
    let mut preds = Vec::new();
    let mut gu0: Vec<Vec<Tensor>> = (0..model.layers.len()).map(|_| Vec::new()).collect();
    let mut state = model.zero_state(1);
    let w = model.inference_weights();
    for t in 0..is[0] {
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
    Ok((preds, gu0))
}

/// One layer's row of the strip: the channel that varies most over the sequence, at the frames
/// `used`, scaled to [0, 1] by one range for the whole row so that its columns compare.
fn busiest_channel_row(seq: &[Tensor], used: &[usize]) -> (Vec<Tensor>, i64) {
    let all = Tensor::stack(seq, 0); // [T, C, H, W]
    let c = all
        .var_dim([0, 2, 3].as_slice(), false, false)
        .argmax(0, false)
        .int64_value(&[]);
    let picked: Vec<Tensor> = used.iter().map(|&f| all.get(f as i64).get(c)).collect();
    let lo = Tensor::stack(&picked, 0).min().double_value(&[]);
    let hi = Tensor::stack(&picked, 0).max().double_value(&[]);
    let span = (hi - lo).max(1e-9);
    (picked.iter().map(|p| (p - lo) / span).collect(), c)
}

/// Cells in a grid with a label left of each row and above each column.
struct Strip<'a> {
    /// 2-d tensors in [0, 1], `rows[r][c]`.
    rows: &'a [Vec<Tensor>],
    row_labels: &'a [String],
    col_labels: &'a [String],
}

impl Strip<'_> {
    /// Draws the cells at the image's size x SCALE (smaller maps stretched, nearest) with their
    /// labels, through the project's one PNG path.
    fn write(&self, path: &Path, (h, w): (usize, usize)) -> Result<(), FigureError> {
        let mut cells = Vec::with_capacity(self.rows.len());
        for row in self.rows {
            let mut out = Vec::with_capacity(row.len());
            for cell in row {
                let size = cell.size();
                let values = Vec::<f32>::try_from(cell.to_kind(Kind::Float).flatten(0, -1))
                    .map_err(|e| write_err(path, e))?;
                out.push(Cell {
                    width: size[1] as usize,
                    height: size[0] as usize,
                    values,
                });
            }
            cells.push(out);
        }
        let cell = ((w * SCALE) as u32, (h * SCALE) as u32);
        mtanet_plot::image_grid(path, &cells, self.row_labels, self.col_labels, cell)
            .map_err(|e| write_err(path, e))
    }
}

fn write_err(path: &Path, e: impl ToString) -> FigureError {
    FigureError::Write {
        path: path.to_owned(),
        detail: e.to_string(),
    }
}
