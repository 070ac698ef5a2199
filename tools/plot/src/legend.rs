//! The legend, drawn in a column right of the chart: plotters' own sits on the plotting area
//! and hides the data it overlaps.

use plotters::prelude::*;

use crate::{Area, DrawResult, colour, text};

/// How an entry's sample looks.
#[derive(Clone, Copy)]
pub enum Swatch {
    Line { colour: [u8; 3], width: u32 },
    Dashed { colour: [u8; 3] },
    Dot { colour: [u8; 3] },
    Block { colour: [u8; 3] },
}

/// The legend column's width in pixels.
pub const WIDTH: u32 = 190;
const ROW: i32 = 20;

/// Splits `area` into the chart's part and the legend column on its right.
pub fn split<'b>(area: &Area<'b>) -> (Area<'b>, Area<'b>) {
    let (w, _) = area.dim_in_pixel();
    area.split_horizontally(w.saturating_sub(WIDTH))
}

/// Draws `entries` top-down in `column`, starting `top` pixels down (below the chart's title).
pub fn draw(column: &Area, top: i32, entries: &[(String, Swatch)]) -> DrawResult {
    for (k, (name, swatch)) in entries.iter().enumerate() {
        let y = top + k as i32 * ROW;
        match *swatch {
            Swatch::Line { colour: c, width } => {
                column.draw(&PathElement::new(
                    vec![(4, y), (28, y)],
                    colour(c).stroke_width(width),
                ))?;
            }
            Swatch::Dashed { colour: c } => {
                for x in [4, 13, 22] {
                    column.draw(&PathElement::new(vec![(x, y), (x + 6, y)], colour(c)))?;
                }
            }
            Swatch::Block { colour: c } => {
                column.draw(&Rectangle::new(
                    [(8, y - 6), (24, y + 6)],
                    colour(c).filled(),
                ))?;
            }
            Swatch::Dot { colour: c } => {
                column.draw(&Circle::new((16, y), 5, colour(c).filled()))?;
            }
        }
        column.draw_text(name, &text(14), (36, y - 6))?;
    }
    Ok(())
}
