//! From a curvature profile to waypoints: curvature ramps between the holds, integration along
//! the line, and the straights' lengths solved so that the loop ends where it started.

use super::profile::{Hold, Profile};
use crate::dist;

/// Curvature changes linearly over this much line where two holds meet (a clothoid), so the
/// steering the car needs never jumps; half of it is taken from each side, which keeps the
/// total turn unchanged.
const RAMP_M: f64 = 0.05;
/// Waypoint spacing as in `scenes/tracks/make_tracks.py`: on a bend the polyline strays at most
/// this far from the true curve, with waypoints at most `MAX_BEND_SPACING_M` apart; straights
/// get a few points only. Every waypoint becomes a geom, and geoms cost physics time.
const SAGITTA_M: f64 = 0.0005;
const MAX_BEND_SPACING_M: f64 = 0.04;
const STRAIGHT_SPACING_M: f64 = 0.25;
/// Integration step inside a ramp (its curvature is not constant over a waypoint interval).
const RAMP_STEP_M: f64 = 0.002;
/// Waypoints closer than this are merged: a hold shortened to almost nothing by its ramps
/// would otherwise leave a near-duplicate point.
const MERGE_M: f64 = 0.001;

/// A stretch whose curvature goes linearly from `k0` to `k1`.
struct Piece {
    len: f64,
    k0: f64,
    k1: f64,
    /// A straight's index and share of its length (how the end point moves with that length).
    straight: Option<(usize, f64)>,
}

/// Shortest a hold can become: a straight may shrink to its minimum when the loop is closed.
fn min_len(p: &Profile, h: &Hold) -> f64 {
    match h.straight {
        Some((v, share)) => share * p.straight_min[v],
        None => h.len,
    }
}

fn pieces(p: &Profile) -> Vec<Piece> {
    let h = &p.holds;
    let n = h.len();
    // Ramp j joins holds j and j+1. None across the start: both ends are the same straight.
    // Each is at most the shorter neighbour's minimum, so no hold's remainder goes negative.
    let ramps: Vec<f64> = (0..n - 1)
        .map(|j| match h[j].k == h[j + 1].k {
            true => 0.0,
            false => RAMP_M.min(min_len(p, &h[j])).min(min_len(p, &h[j + 1])),
        })
        .collect();
    let mut out = Vec::with_capacity(2 * n);
    for i in 0..n {
        let before = if i > 0 { ramps[i - 1] / 2.0 } else { 0.0 };
        let after = if i + 1 < n { ramps[i] / 2.0 } else { 0.0 };
        out.push(Piece {
            len: h[i].len - before - after,
            k0: h[i].k,
            k1: h[i].k,
            straight: h[i].straight,
        });
        if i + 1 < n && ramps[i] > 0.0 {
            out.push(Piece {
                len: ramps[i],
                k0: h[i].k,
                k1: h[i + 1].k,
                straight: None,
            });
        }
    }
    out
}

/// Moves `pose` (x, y, heading) along an arc of curvature `k` for `h` metres, exactly.
fn advance(pose: &mut [f64; 3], k: f64, h: f64) {
    let half = k * h / 2.0;
    let chord = if half.abs() < 1e-9 {
        h
    } else {
        h * half.sin() / half
    };
    let mid = pose[2] + half;
    pose[0] += chord * mid.cos();
    pose[1] += chord * mid.sin();
    pose[2] += 2.0 * half;
}

struct Traced {
    points: Vec<[f64; 2]>,
    end: [f64; 3],
    /// How the end point moves per metre added to each straight.
    pull: Vec<[f64; 2]>,
}

/// Integrates the pieces from the origin heading +x; the first point is the origin.
fn trace(pieces: &[Piece], straights: usize) -> Traced {
    let mut pose = [0.0_f64; 3];
    let mut points = vec![[0.0, 0.0]];
    let mut pull = vec![[0.0; 2]; straights];
    for pc in pieces {
        if let Some((v, share)) = pc.straight {
            pull[v][0] += share * pose[2].cos();
            pull[v][1] += share * pose[2].sin();
        }
        if pc.len <= 0.0 {
            continue;
        }
        let k_max = pc.k0.abs().max(pc.k1.abs());
        let spacing = match k_max < 1e-12 {
            true => STRAIGHT_SPACING_M,
            false => (8.0 * SAGITTA_M / k_max).sqrt().min(MAX_BEND_SPACING_M),
        };
        let n = (pc.len / spacing).ceil().max(1.0) as usize;
        let sub = match pc.k0 == pc.k1 {
            true => 1,
            false => ((pc.len / n as f64) / RAMP_STEP_M).ceil() as usize,
        };
        let h = pc.len / (n * sub) as f64;
        for i in 0..n {
            for j in 0..sub {
                // Midpoint curvature: exact turn for a linear ramp.
                let s_mid = ((i * sub + j) as f64 + 0.5) * h;
                advance(&mut pose, pc.k0 + (pc.k1 - pc.k0) * s_mid / pc.len, h);
            }
            let q = [pose[0], pose[1]];
            if dist(q, *points.last().expect("origin")) >= MERGE_M {
                points.push(q);
            }
        }
    }
    Traced {
        points,
        end: pose,
        pull,
    }
}

/// Lengthens and shortens the straights (least change, weighted by length) so the loop ends at
/// its start, and returns the waypoints without the closing repeat. `None` if a straight would
/// fall below its minimum or the straights all run one way and cannot close the gap.
pub(super) fn close(p: &mut Profile) -> Option<Vec<[f64; 2]>> {
    let nv = p.straight_min.len();
    let t = trace(&pieces(p), nv);
    let mut len = vec![0.0; nv];
    for h in &p.holds {
        if let Some((v, _)) = h.straight {
            len[v] += h.len;
        }
    }
    // The end point is linear in the straights' lengths (their headings do not depend on them):
    // minimise sum(d_v^2 / len_v) subject to sum(d_v pull_v) = -end.
    let mut m = [[0.0; 2]; 2];
    for (&w, u) in len.iter().zip(&t.pull) {
        for (a, row) in m.iter_mut().enumerate() {
            for (b, cell) in row.iter_mut().enumerate() {
                *cell += w * u[a] * u[b];
            }
        }
    }
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    if det.abs() < 1e-6 * (m[0][0] + m[1][1]).powi(2) {
        return None;
    }
    let g = [-t.end[0], -t.end[1]];
    let lambda = [
        (m[1][1] * g[0] - m[0][1] * g[1]) / det,
        (m[0][0] * g[1] - m[1][0] * g[0]) / det,
    ];
    for ((l, u), min) in len.iter_mut().zip(&t.pull).zip(&p.straight_min) {
        *l += *l * (u[0] * lambda[0] + u[1] * lambda[1]);
        if *l < *min {
            return None;
        }
    }
    for h in &mut p.holds {
        if let Some((v, share)) = h.straight {
            h.len = share * len[v];
        }
    }
    let mut t = trace(&pieces(p), nv);
    if t.end[0].hypot(t.end[1]) > 1e-9 {
        return None;
    }
    // The last waypoints land on the start: the closing segment is implicit.
    while t.points.len() > 1 && dist(*t.points.last().expect("non-empty"), [0.0, 0.0]) < MERGE_M {
        t.points.pop();
    }
    Some(t.points)
}
