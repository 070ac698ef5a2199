//! The line tracer's tracks, as data with no physics behind them: a closed polyline of
//! waypoints in a CSV file (see `parse.rs` for the format), or drawn from a seed by the
//! generator (`generated:N`, see `generate.rs`).
//!
//! A [`Track`] is validated once when it is built (`check.rs`), so everything downstream (MJCF
//! generation, ground truth, the teacher) can assume a simple, closed, drivable line.

mod check;
mod generate;
mod parse;

use std::path::{Path, PathBuf};

pub use check::{MIN_BEND_RADIUS_M, MIN_CLEARANCE_M};
pub use generate::{
    GENERATED_MIN_RADIUS_M, GENERATED_PREFIX, HAIRPIN_DEFAULT_CURVATURE, HAIRPINS_PREFIX,
    LENGTH_RANGE_M, generate, generate_counting,
};

/// Line width used when the file does not say (metres; the paper's tape is about this wide).
pub const DEFAULT_LINE_WIDTH_M: f64 = 0.025;

/// Why a track could not be loaded. Every variant names the file; the ones about a place in the
/// file name its 1-based line so the author can go straight there.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// The file could not be read at all.
    #[error("track {path}: cannot read file: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A line is not `x,y` with two numbers, or a `# width=` comment is malformed.
    #[error("track {path}, line {line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// A coordinate or the width is NaN or infinite.
    #[error("track {path}, line {line}: coordinate `{value}` is not finite")]
    NonFinite {
        path: PathBuf,
        line: usize,
        value: String,
    },
    /// A closed line needs at least a triangle.
    #[error("track {path}: has {count} distinct points, a closed track needs at least 3")]
    TooFewPoints { path: PathBuf, count: usize },
    /// Two consecutive points coincide, so the segment between them has no direction.
    #[error("track {path}, line {line}: point repeats the previous point (zero-length segment)")]
    DuplicatePoint { path: PathBuf, line: usize },
    /// The polyline crosses itself; the two segments are named by the file lines of their ends.
    #[error(
        "track {path}: segment {a} (lines {a_lines:?}) crosses segment {b} (lines {b_lines:?})"
    )]
    SelfCrossing {
        path: PathBuf,
        a: usize,
        a_lines: (usize, usize),
        b: usize,
        b_lines: (usize, usize),
    },
    /// Two parts of the line far apart along the track come so close that the sensors would see
    /// both.
    #[error(
        "track {path}: segment {a} (lines {a_lines:?}) passes {dist_m:.3} m from segment {b} (lines {b_lines:?}), minimum clearance is {min_m} m"
    )]
    TooClose {
        path: PathBuf,
        a: usize,
        a_lines: (usize, usize),
        b: usize,
        b_lines: (usize, usize),
        dist_m: f64,
        min_m: f64,
    },
    /// `generated:` or `hairpins:` is not followed by a seed (and a curvature).
    #[error(
        "track {path}: expected `generated:N` or `hairpins:N[:K]` with N a whole number from 0 to 2^64-1 (the seed) and K the tightest curvature in 1/m"
    )]
    GeneratedName { path: PathBuf },
    /// `hairpins:N:K` asks for bends tighter than the checks allow, or no tighter than
    /// `generated:N`'s.
    #[error("track {path}: tightest curvature {curvature} 1/m is outside {min:.2}..={max:.2} 1/m")]
    HairpinCurvature {
        path: PathBuf,
        curvature: f64,
        min: f64,
        max: f64,
    },
    /// No candidate of the generator passed the checks (a bug in the generator: a few tries
    /// are normal).
    #[error("track {path}: the generator found no valid track in {candidates} candidates")]
    GeneratorGaveUp { path: PathBuf, candidates: u32 },
    /// The line bends more sharply than the car can follow.
    #[error(
        "track {path}, line {line} (point {point}): bend radius {radius_m:.3} m is below the minimum {min_m} m"
    )]
    TooTight {
        path: PathBuf,
        line: usize,
        point: usize,
        radius_m: f64,
        min_m: f64,
    },
}

/// A validated closed track. Point `i` joins point `i+1`, and the last point joins the first.
#[derive(Debug, Clone)]
pub struct Track {
    path: PathBuf,
    points: Vec<[f64; 2]>,
    /// File line of each point, for error messages and diagnostics.
    lines: Vec<usize>,
    /// Arc length at each point; `cum[n]` is the total length (the closing segment included).
    cum: Vec<f64>,
    line_width: f64,
}

/// The closest point of the track to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Arc length of the closest point, in `[0, length)`.
    pub s: f64,
    /// The closest point on the line.
    pub point: [f64; 2],
    /// Distance from the query point to the line (>= 0).
    pub distance: f64,
    /// Index of the segment holding the closest point.
    pub segment: usize,
}

impl Track {
    /// Loads and validates a track file, or generates the track when `path` is `generated:N`:
    /// every config key and flag that names a track goes through here, so all accept both.
    pub fn load(path: &Path) -> Result<Track, TrackError> {
        if let Some((seed, style)) = generate::spec_of(path)? {
            return generate::generate_styled(&path.to_string_lossy(), seed, &style)
                .map(|(t, _)| t);
        }
        let text = std::fs::read_to_string(path).map_err(|source| TrackError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parses and validates track text; `path` is only used to name the source in errors.
    pub fn parse(path: &Path, text: &str) -> Result<Track, TrackError> {
        let parsed = parse::parse(path, text)?;
        Self::from_parts(path, parsed.points, parsed.lines, parsed.line_width)
    }

    /// Builds a track from points already in memory (line numbers are then the point numbers,
    /// and a bad width is reported as line 0).
    pub fn from_points(
        name: &str,
        points: Vec<[f64; 2]>,
        line_width: f64,
    ) -> Result<Track, TrackError> {
        let path = Path::new(name);
        parse::check_width(line_width).map_err(|message| TrackError::Parse {
            path: path.to_path_buf(),
            line: 0,
            message,
        })?;
        if let Some(i) = points
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(TrackError::NonFinite {
                path: path.to_path_buf(),
                line: i + 1,
                value: format!("{:?}", points[i]),
            });
        }
        let lines = (1..=points.len()).collect();
        Self::from_parts(path, points, lines, line_width)
    }

    fn from_parts(
        path: &Path,
        points: Vec<[f64; 2]>,
        lines: Vec<usize>,
        line_width: f64,
    ) -> Result<Track, TrackError> {
        let (points, lines) = check::check(path, points, lines)?;
        let n = points.len();
        let mut cum = Vec::with_capacity(n + 1);
        let mut s = 0.0;
        cum.push(0.0);
        for i in 0..n {
            s += dist(points[i], points[(i + 1) % n]);
            cum.push(s);
        }
        Ok(Track {
            path: path.to_path_buf(),
            points,
            lines,
            cum,
            line_width,
        })
    }

    /// Where the track came from (a file path, or the name given to `from_points`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Total length of the closed line, metres.
    pub fn length_m(&self) -> f64 {
        self.cum[self.points.len()]
    }

    /// Width of the dark line, metres.
    pub fn line_width_m(&self) -> f64 {
        self.line_width
    }

    /// The waypoints (the closing segment from the last to the first is implicit).
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// File line of each waypoint.
    pub fn point_lines(&self) -> &[usize] {
        &self.lines
    }

    /// Radius of the tightest bend, measured as the check measures it (over a few cm of line);
    /// infinite for a line that never turns.
    pub fn min_bend_radius_m(&self) -> f64 {
        check::tightest_bend(&self.points, &self.cum).map_or(f64::INFINITY, |(_, r)| r)
    }

    /// The track in the file format `load` reads (`parse.rs`), 5 decimals (10 um), with
    /// `comments` as `#` lines at the top.
    pub fn to_csv(&self, comments: &[&str]) -> String {
        parse::format(&self.points, self.line_width, comments)
    }

    /// Number of segments (= number of points, the line being closed).
    pub fn segment_count(&self) -> usize {
        self.points.len()
    }

    /// Segment `i` as (start, end); `i` wraps.
    pub fn segment(&self, i: usize) -> ([f64; 2], [f64; 2]) {
        let n = self.points.len();
        (self.points[i % n], self.points[(i + 1) % n])
    }

    /// Point and heading (radians, world frame) at arc length `s` (wrapped into the track).
    pub fn pose_at(&self, s: f64) -> ([f64; 2], f64) {
        let len = self.length_m();
        let s = s.rem_euclid(len);
        // cum is sorted; the segment is the last one starting at or before s.
        let i = match self.cum.binary_search_by(|c| c.total_cmp(&s)) {
            Ok(i) => i,
            Err(i) => i - 1,
        }
        .min(self.points.len() - 1);
        let (a, b) = self.segment(i);
        let seg_len = self.cum[i + 1] - self.cum[i];
        let t = ((s - self.cum[i]) / seg_len).clamp(0.0, 1.0);
        let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        (p, (b[1] - a[1]).atan2(b[0] - a[0]))
    }

    /// Signed curvature (1/m, left turns positive) at arc length `s`: that of the circle through
    /// the line's points at `s - half_window_m`, `s` and `s + half_window_m` (Menger curvature).
    /// On a polyline's arcs it is the arc's own curvature whatever the waypoint spacing; a
    /// shipped track's corner comes out as its turn spread over the window.
    pub fn curvature_at(&self, s: f64, half_window_m: f64) -> f64 {
        let h = half_window_m.max(1e-6);
        let (a, _) = self.pose_at(s - h);
        let (b, _) = self.pose_at(s);
        let (c, _) = self.pose_at(s + h);
        let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        let sides = dist(a, b) * dist(b, c) * dist(a, c);
        if sides <= 0.0 {
            0.0
        } else {
            2.0 * cross / sides
        }
    }

    /// Closest point of the line to `q`. Global search: a few hundred segments cost ~1 us, and a
    /// global search stays right after teleports (`World::set_pose`).
    pub fn project(&self, q: [f64; 2]) -> Projection {
        let mut best = Projection {
            s: 0.0,
            point: self.points[0],
            distance: f64::INFINITY,
            segment: 0,
        };
        for i in 0..self.points.len() {
            let (a, b) = self.segment(i);
            let (t, p) = closest_on_segment(a, b, q);
            let d = dist(p, q);
            if d < best.distance {
                let s = self.cum[i] + t * (self.cum[i + 1] - self.cum[i]);
                best = Projection {
                    s: if s >= self.length_m() { 0.0 } else { s },
                    point: p,
                    distance: d,
                    segment: i,
                };
            }
        }
        best
    }
}

/// Euclidean distance between two points.
pub fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Parameter `t` in [0,1] and the point of segment `a`-`b` closest to `q`.
fn closest_on_segment(a: [f64; 2], b: [f64; 2], q: [f64; 2]) -> (f64, [f64; 2]) {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (t, [a[0] + t * d[0], a[1] + t * d[1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(side: f64, n_per_side: usize) -> Vec<[f64; 2]> {
        let corners = [[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]];
        let mut pts = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            for j in 0..n_per_side {
                let t = j as f64 / n_per_side as f64;
                pts.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        pts
    }

    #[test]
    fn circle_length_and_projection() {
        let r = 0.5;
        let n = 200;
        let pts: Vec<_> = (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * std::f64::consts::TAU;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let t = Track::from_points("circle", pts, 0.02).unwrap();
        assert!((t.length_m() - std::f64::consts::TAU * r).abs() < 1e-3);
        let p = t.project([0.0, 0.6]);
        assert!((p.distance - 0.1).abs() < 1e-3, "{p:?}");
        assert!((p.s - t.length_m() / 4.0).abs() < 1e-3, "{p:?}");
        let (q, heading) = t.pose_at(t.length_m() / 4.0);
        assert!((q[0]).abs() < 1e-3 && (q[1] - r).abs() < 1e-3);
        // Heading -x at the top of a counter-clockwise circle (+-pi).
        assert!(heading.cos() < -0.99, "{heading}");
    }

    /// A counter-clockwise circle of radius 0.5 m has curvature +2 everywhere, across the
    /// start too; driven clockwise, -2.
    #[test]
    fn curvature_of_a_circle_is_one_over_its_radius_with_its_turn_sign() {
        let r = 0.5;
        let ccw: Vec<_> = (0..400)
            .map(|i| {
                let a = i as f64 / 400.0 * std::f64::consts::TAU;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let mut cw = ccw.clone();
        cw.reverse();
        let (ccw, cw) = (
            Track::from_points("ccw", ccw, 0.02).unwrap(),
            Track::from_points("cw", cw, 0.02).unwrap(),
        );
        for s in [0.0, 0.7, ccw.length_m() - 0.01] {
            let k = ccw.curvature_at(s, 0.05);
            assert!((k - 2.0).abs() < 0.04, "{s}: {k}");
            assert!((cw.curvature_at(s, 0.05) + 2.0).abs() < 0.04);
        }
    }

    #[test]
    fn in_memory_points_are_validated_too() {
        let ok = vec![[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]];
        let e = Track::from_points("mem", vec![[0.0, 0.0], [f64::NAN, 0.0], [0.5, 1.0]], 0.02);
        assert!(matches!(e, Err(TrackError::NonFinite { line: 2, .. })));
        let e = Track::from_points("mem", ok.clone(), f64::NAN);
        assert!(matches!(e, Err(TrackError::Parse { line: 0, .. })));
        let e = Track::from_points("mem", ok, 0.5);
        assert!(matches!(e, Err(TrackError::Parse { .. })));
    }

    #[test]
    fn sharp_square_is_too_tight() {
        // Four 90-degree corners with no rounding: the check must name a corner.
        let err = Track::from_points("sq", square(1.0, 10), 0.02).unwrap_err();
        assert!(matches!(err, TrackError::TooTight { .. }), "{err}");
    }
}
