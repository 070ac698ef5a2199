//! Validation of a closed polyline: enough points, no zero-length segments, no self-crossing, no
//! two distant parts of the line close enough to confuse the sensors, no bend too tight.

use std::path::Path;

use super::{TrackError, dist};

/// Smallest bend radius the teacher car follows reliably (the sensor bar sits 8.5 cm ahead of
/// the axle, so a tighter bend swings the line out from under the sensors before the car turns).
pub const MIN_BEND_RADIUS_M: f64 = 0.07;
/// Bends are measured over this much line, so that a sharp kink cannot hide between two long
/// segments and a densely sampled curve is not judged by one noisy vertex.
const BEND_WINDOW_M: f64 = 0.04;
/// Two parts of the line that are far apart along the track must be at least this far apart in
/// the plane: the camera sees about +-6 cm sideways, the sensors +-3 cm.
pub const MIN_CLEARANCE_M: f64 = 0.10;
/// Parts of the line closer than this along the track are neighbours, not a second pass.
const NEIGHBOUR_ARC_M: f64 = 0.15;

pub(super) fn check(
    path: &Path,
    mut points: Vec<[f64; 2]>,
    mut lines: Vec<usize>,
) -> Result<(Vec<[f64; 2]>, Vec<usize>), TrackError> {
    let path_buf = || path.to_path_buf();
    // An explicitly closed file (last point = first point) is the same track.
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
        lines.pop();
    }
    for i in 1..points.len() {
        if dist(points[i], points[i - 1]) < 1e-9 {
            return Err(TrackError::DuplicatePoint {
                path: path_buf(),
                line: lines[i],
            });
        }
    }
    if points.len() < 3 {
        return Err(TrackError::TooFewPoints {
            path: path_buf(),
            count: points.len(),
        });
    }
    let n = points.len();
    let mut cum = vec![0.0; n + 1];
    for i in 0..n {
        cum[i + 1] = cum[i] + dist(points[i], points[(i + 1) % n]);
    }
    check_crossings_and_clearance(path, &points, &lines, &cum)?;

    if let Some((point, radius)) = tightest_bend(&points, &cum)
        && radius < MIN_BEND_RADIUS_M
    {
        return Err(TrackError::TooTight {
            path: path_buf(),
            line: lines[point],
            point,
            radius_m: radius,
            min_m: MIN_BEND_RADIUS_M,
        });
    }
    Ok((points, lines))
}

/// No two segments cross, and no two parts of the line far apart along the track come close.
fn check_crossings_and_clearance(
    path: &Path,
    points: &[[f64; 2]],
    lines: &[usize],
    cum: &[f64],
) -> Result<(), TrackError> {
    let n = points.len();
    let length = cum[n];
    let seg_lines = |i: usize| (lines[i], lines[(i + 1) % n]);
    let seg = |i: usize| (points[i], points[(i + 1) % n]);
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            let (a0, a1) = seg(i);
            let (b0, b1) = seg(j);
            if !adjacent && segments_intersect(a0, a1, b0, b1) {
                return Err(TrackError::SelfCrossing {
                    path: path.to_path_buf(),
                    a: i,
                    a_lines: seg_lines(i),
                    b: j,
                    b_lines: seg_lines(j),
                });
            }
            // Arc gap between the two segments, the short way round the loop.
            let gap_fwd = cum[j] - cum[i + 1];
            let gap_back = length - cum[j + 1] + cum[i];
            if gap_fwd.min(gap_back) <= NEIGHBOUR_ARC_M {
                continue;
            }
            let d = segment_distance(a0, a1, b0, b1);
            if d < MIN_CLEARANCE_M {
                return Err(TrackError::TooClose {
                    path: path.to_path_buf(),
                    a: i,
                    a_lines: seg_lines(i),
                    b: j,
                    b_lines: seg_lines(j),
                    dist_m: d,
                    min_m: MIN_CLEARANCE_M,
                });
            }
        }
    }
    Ok(())
}

/// Signed turn (radians, left positive) at vertex `i`.
fn turn_at(points: &[[f64; 2]], i: usize) -> f64 {
    let n = points.len();
    let (p, c, q) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
    let h_in = (c[1] - p[1]).atan2(c[0] - p[0]);
    let h_out = (q[1] - c[1]).atan2(q[0] - c[0]);
    let mut d = h_out - h_in;
    while d > std::f64::consts::PI {
        d -= std::f64::consts::TAU;
    }
    while d < -std::f64::consts::PI {
        d += std::f64::consts::TAU;
    }
    d
}

/// The vertex starting the sharpest window of line, and the radius there: the turn accumulated
/// over the vertices within `BEND_WINDOW_M` ahead, divided by the length of line that turn is
/// spread over (capped at half a window beyond the first and last vertex).
pub(super) fn tightest_bend(points: &[[f64; 2]], cum: &[f64]) -> Option<(usize, f64)> {
    let n = points.len();
    let seg_len = |k: usize| cum[k % n + 1] - cum[k % n];
    let turns: Vec<f64> = (0..n).map(|i| turn_at(points, i)).collect();
    let mut best: Option<(usize, f64)> = None;
    for i in 0..n {
        let mut turn = 0.0;
        let mut k = i;
        let mut span_inner = 0.0;
        // Walk forward while the next vertex is still inside the window (at most once round).
        loop {
            turn += turns[k % n];
            let next = span_inner + seg_len(k);
            if next > BEND_WINDOW_M || k + 1 - i >= n {
                break;
            }
            span_inner = next;
            k += 1;
        }
        let half = BEND_WINDOW_M / 2.0;
        let span = (seg_len(i + n - 1) / 2.0).min(half) + span_inner + (seg_len(k) / 2.0).min(half);
        if turn.abs() < 1e-12 {
            continue;
        }
        let r = span / turn.abs();
        if best.is_none_or(|(_, b)| r < b) {
            best = Some((i, r));
        }
    }
    best
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn on_segment(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0]) - 1e-12
        && p[0] <= a[0].max(b[0]) + 1e-12
        && p[1] >= a[1].min(b[1]) - 1e-12
        && p[1] <= a[1].max(b[1]) + 1e-12
}

/// True if the closed segments touch or cross (touching counts: the drawn lines would merge).
fn segments_intersect(a0: [f64; 2], a1: [f64; 2], b0: [f64; 2], b1: [f64; 2]) -> bool {
    let eps = 1e-12;
    let d1 = orient(b0, b1, a0);
    let d2 = orient(b0, b1, a1);
    let d3 = orient(a0, a1, b0);
    let d4 = orient(a0, a1, b1);
    if ((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps))
        && ((d3 > eps && d4 < -eps) || (d3 < -eps && d4 > eps))
    {
        return true;
    }
    (d1.abs() <= eps && on_segment(b0, b1, a0))
        || (d2.abs() <= eps && on_segment(b0, b1, a1))
        || (d3.abs() <= eps && on_segment(a0, a1, b0))
        || (d4.abs() <= eps && on_segment(a0, a1, b1))
}

fn segment_distance(a0: [f64; 2], a1: [f64; 2], b0: [f64; 2], b1: [f64; 2]) -> f64 {
    if segments_intersect(a0, a1, b0, b1) {
        return 0.0;
    }
    let pd = |a, b, q| dist(super::closest_on_segment(a, b, q).1, q);
    pd(a0, a1, b0)
        .min(pd(a0, a1, b1))
        .min(pd(b0, b1, a0))
        .min(pd(b0, b1, a1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_segments() {
        assert!(segments_intersect(
            [0.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [1.0, 0.0]
        ));
        assert!(!segments_intersect(
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [1.0, 1.0]
        ));
        // T-junction: touching counts.
        assert!(segments_intersect(
            [0.0, 0.0],
            [2.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0]
        ));
    }

    #[test]
    fn bend_radius_of_sampled_circle() {
        for (r, n) in [(0.3, 60), (0.3, 200), (0.15, 40)] {
            let pts: Vec<_> = (0..n)
                .map(|i| {
                    let a = i as f64 / n as f64 * std::f64::consts::TAU;
                    [r * a.cos(), r * a.sin()]
                })
                .collect();
            let mut cum = vec![0.0];
            for i in 0..n {
                let l = cum[i] + dist(pts[i], pts[(i + 1) % n]);
                cum.push(l);
            }
            let (_, est) = tightest_bend(&pts, &cum).unwrap();
            assert!((est - r).abs() / r < 0.05, "r={r} n={n} est={est}");
        }
    }
}
