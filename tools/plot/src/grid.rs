//! A labelled grid of grayscale images (the model's figure strip): a label left of each row
//! and above each column, cells scaled to one size, nearest pixel, so small maps stay blocky.

use std::path::Path;

use plotters::prelude::*;

use crate::{PlotError, render, text};

/// A grayscale image, row-major, values in [0, 1] (others are clamped).
pub struct Cell {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

const GAP: u32 = 3;
const FONT: u32 = 16;

/// Draws `rows[r][c]` at `cell` = (width, height) pixels each into `path`.
pub fn image_grid(
    path: &Path,
    rows: &[Vec<Cell>],
    row_labels: &[String],
    col_labels: &[String],
    (cw, ch): (u32, u32),
) -> Result<(), PlotError> {
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let style = text(FONT);
    let longest = row_labels
        .iter()
        .filter_map(|l| style.font.box_size(l).ok())
        .map(|(w, _)| w)
        .max()
        .unwrap_or(0);
    let (left, top) = (longest + 3 * GAP, FONT + 3 * GAP);
    let width = left + cols * (cw + GAP) + GAP;
    let height = top + rows.len() as u32 * (ch + GAP) + GAP;
    let origin = |r: usize, c: usize| {
        (
            (left + GAP + c as u32 * (cw + GAP)) as i32,
            (top + GAP + r as u32 * (ch + GAP)) as i32,
        )
    };
    render(path, (width, height), |root| {
        root.fill(&WHITE)?;
        for (r, row) in rows.iter().enumerate() {
            for (c, cell) in row.iter().enumerate() {
                let (x0, y0) = origin(r, c);
                for y in 0..ch {
                    for x in 0..cw {
                        let sy = y as usize * cell.height / ch as usize;
                        let sx = x as usize * cell.width / cw as usize;
                        let v = cell
                            .values
                            .get(sy * cell.width + sx)
                            .copied()
                            .unwrap_or(1.0);
                        let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                        root.draw_pixel((x0 + x as i32, y0 + y as i32), &RGBColor(g, g, g))?;
                    }
                }
            }
        }
        for (r, label) in row_labels.iter().enumerate() {
            let (_, y0) = origin(r, 0);
            root.draw_text(
                label,
                &style,
                (GAP as i32, y0 + (ch as i32 - FONT as i32) / 2),
            )?;
        }
        for (c, label) in col_labels.iter().enumerate() {
            let (x0, _) = origin(0, c);
            root.draw_text(label, &style, (x0, GAP as i32))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, inked, near};

    #[test]
    fn draws_cells_at_their_size_and_labels() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.png");
        let black = || Cell {
            width: 2,
            height: 1,
            values: vec![0.0, 0.0],
        };
        let rows = vec![vec![black(), black()], vec![black(), black()]];
        let labels = |p: &str| vec![format!("{p}0"), format!("{p}1")];
        image_grid(&path, &rows, &labels("row "), &labels("t="), (40, 20)).unwrap();
        let (w, h, px) = decode(&path);
        // A margin for the labels, then two 40 x 20 px cells with 3 px gaps.
        let left = w - 2 * 43 - 3;
        assert!(
            (30..80).contains(&left),
            "room for \"row 1\" at 16 px: {left}"
        );
        assert_eq!(h, 25 + 2 * 23 + 3);
        assert!(near(&px, [0, 0, 0]) >= 4 * 40 * 20, "the black cells");
        assert!(inked(&px) > 4 * 40 * 20 + 50, "and the labels' ink");
    }
}
