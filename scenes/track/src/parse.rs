//! Track file format:
//!
//! ```text
//! # any comment; `# width=0.025` sets the line width in metres (default 0.025)
//! x,y            <- optional header, only before the first point
//! 0.0,0.0
//! 0.5,0.0
//! ...
//! ```
//!
//! One point a line, metres. The polyline is closed implicitly; repeating the first point at the
//! end is allowed and dropped.

use std::path::Path;

use super::{DEFAULT_LINE_WIDTH_M, TrackError};

/// Widths outside this range are surely a unit mistake (mm instead of m, ...).
const WIDTH_RANGE_M: (f64, f64) = (0.002, 0.2);

pub(super) struct Parsed {
    pub points: Vec<[f64; 2]>,
    pub lines: Vec<usize>,
    pub line_width: f64,
}

pub(super) fn parse(path: &Path, text: &str) -> Result<Parsed, TrackError> {
    let mut points = Vec::new();
    let mut lines = Vec::new();
    let mut line_width = DEFAULT_LINE_WIDTH_M;
    let parse_err = |line: usize, message: String| TrackError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };

    for (idx, raw) in text.lines().enumerate() {
        let line_no = idx + 1;
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            if let Some(w) = width_directive(comment) {
                line_width = parse_width(w).map_err(|m| parse_err(line_no, m))?;
            }
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        // A header is allowed before the first point only, and only if no field is a number:
        // "1.0,abc" is a typo in a point, not a header.
        if points.is_empty() && fields.iter().all(|f| f.parse::<f64>().is_err()) {
            continue;
        }
        if fields.len() != 2 {
            return Err(parse_err(
                line_no,
                format!("expected `x,y` (2 fields), found {} fields", fields.len()),
            ));
        }
        let mut xy = [0.0; 2];
        for (k, f) in fields.iter().enumerate() {
            let v: f64 = f.parse().map_err(|_| {
                parse_err(line_no, format!("{} `{f}` is not a number", ["x", "y"][k]))
            })?;
            if !v.is_finite() {
                return Err(TrackError::NonFinite {
                    path: path.to_path_buf(),
                    line: line_no,
                    value: (*f).to_string(),
                });
            }
            xy[k] = v;
        }
        points.push(xy);
        lines.push(line_no);
    }
    Ok(Parsed {
        points,
        lines,
        line_width,
    })
}

/// The text `parse` reads back to the same points (5 decimals: the 10 um generated tracks are
/// rounded to), header and width included.
pub(super) fn format(points: &[[f64; 2]], line_width: f64, comments: &[&str]) -> String {
    use std::fmt::Write;
    let mut out = String::with_capacity(20 * points.len() + 200);
    for c in comments {
        // One comment, one line: a line break would turn the rest into a point.
        let _ = writeln!(out, "# {}", c.replace(['\n', '\r'], " "));
    }
    let _ = writeln!(out, "# width={line_width}\nx,y");
    for p in points {
        let _ = writeln!(out, "{:.5},{:.5}", p[0], p[1]);
    }
    out
}

/// `width=0.03` (spaces allowed) inside a comment; other comments are free text.
fn width_directive(comment: &str) -> Option<&str> {
    let (key, value) = comment.split_once('=')?;
    (key.trim() == "width").then_some(value.trim())
}

fn parse_width(value: &str) -> Result<f64, String> {
    let w: f64 = value
        .parse()
        .map_err(|_| format!("width `{value}` is not a number"))?;
    check_width(w)?;
    Ok(w)
}

/// NaN fails the range test too.
pub(super) fn check_width(w: f64) -> Result<(), String> {
    if !(WIDTH_RANGE_M.0..=WIDTH_RANGE_M.1).contains(&w) {
        return Err(format!(
            "width {w} m is outside [{}, {}] m",
            WIDTH_RANGE_M.0, WIDTH_RANGE_M.1
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_comments_and_width() {
        let p = parse(
            Path::new("t.csv"),
            "# a track\n# width = 0.03\nx,y\n0,0\n\n1, 0\n1,1\n",
        )
        .unwrap();
        assert_eq!(p.points, vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]);
        assert_eq!(p.lines, vec![4, 6, 7]);
        assert_eq!(p.line_width, 0.03);
    }

    #[test]
    fn header_after_points_is_an_error() {
        let e = parse(Path::new("t.csv"), "0,0\nx,y\n").err().unwrap();
        assert!(matches!(e, TrackError::Parse { line: 2, .. }), "{e}");
    }
}
