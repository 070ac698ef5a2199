//! What a layer might know about the road, per model step, from where the car really was (the
//! model never sees this): the curvature coming up, the car's heading error and lateral offset,
//! and how far it has come since the last bend.

use mtanet_scenes::GroundTruth;
use mtanet_track::Track;

/// Curvature is measured over +-10 cm of line (`Track::curvature_at`): the shipped tracks'
/// arcs are polylines of 4 cm chords, and over +-5 cm their curvature wobbles by 15%, over
/// +-10 cm by 4%.
pub const CURVATURE_HALF_WINDOW_M: f64 = 0.1;
/// A bend is line whose |curvature| is at least this (a radius of 0.67 m or less): the oval's
/// half circles (0.4 m) and every generated hairpin or corner are bends, the long sweeping
/// arcs of generated tracks (radius above 0.67 m) and straights are not.
pub const BEND_CURVATURE_PER_M: f64 = 1.5;

/// The read-out targets: name and meaning, in column order.
pub const TARGETS: [(&str, &str); 5] = [
    (
        "curvature_0.5s",
        "curvature of the line (1/m) the arc length ahead that the car covers at its mean speed in 0.5 s",
    ),
    ("curvature_1s", "the same, 1 s ahead"),
    (
        "heading_error",
        "the car's heading minus the line's (rad), now",
    ),
    (
        "lateral_offset",
        "signed distance of the line from the sensor bar (m), now",
    ),
    (
        "since_bend_m",
        "line length (m) since the car's position last was on a bend",
    ),
];

/// Targets per sample `[N][TARGETS]`, and the lap each sample is on (for the folds).
pub struct Targets {
    pub values: Vec<[f64; 5]>,
    pub laps: Vec<u32>,
    pub mean_speed_mps: f64,
}

impl Targets {
    /// For the truths of the model's steps, `step_s` apart.
    pub fn new(track: &Track, truth: &[GroundTruth], step_s: f64) -> Self {
        let len = track.length_m();
        let mut progress = 0.0;
        for w in truth.windows(2) {
            let mut ds = w[1].track_s - w[0].track_s;
            // The short way round the loop (a car moves far less than half a lap per step).
            if ds > len / 2.0 {
                ds -= len;
            } else if ds < -len / 2.0 {
                ds += len;
            }
            progress += ds;
        }
        let seconds = step_s * truth.len().saturating_sub(1) as f64;
        let mean_speed_mps = if seconds > 0.0 {
            progress / seconds
        } else {
            0.0
        };
        let since = SinceBend::new(track);
        let curvature = |s: f64| track.curvature_at(s, CURVATURE_HALF_WINDOW_M);
        let values = truth
            .iter()
            .map(|t| {
                let s = t.track_s;
                [
                    curvature(s + 0.5 * mean_speed_mps),
                    curvature(s + mean_speed_mps),
                    heading_error(track, t),
                    t.lateral_m,
                    since.at(s),
                ]
            })
            .collect();
        Self {
            values,
            laps: truth.iter().map(|t| t.laps).collect(),
            mean_speed_mps,
        }
    }
}

/// The car's heading minus the line's direction over the curvature window at its position,
/// in (-pi, pi].
fn heading_error(track: &Track, t: &GroundTruth) -> f64 {
    let (a, _) = track.pose_at(t.track_s - CURVATURE_HALF_WINDOW_M);
    let (b, _) = track.pose_at(t.track_s + CURVATURE_HALF_WINDOW_M);
    let line = (b[1] - a[1]).atan2(b[0] - a[0]);
    let mut e = t.yaw - line;
    while e > std::f64::consts::PI {
        e -= std::f64::consts::TAU;
    }
    while e <= -std::f64::consts::PI {
        e += std::f64::consts::TAU;
    }
    e
}

/// Line length back from a point to the last bend, tabulated every 5 mm round the loop.
struct SinceBend {
    ds: f64,
    table: Vec<f64>,
}

impl SinceBend {
    fn new(track: &Track) -> Self {
        let ds = 0.005;
        let n = (track.length_m() / ds).ceil() as usize;
        let bend: Vec<bool> = (0..n)
            .map(|i| {
                track
                    .curvature_at(i as f64 * ds, CURVATURE_HALF_WINDOW_M)
                    .abs()
                    >= BEND_CURVATURE_PER_M
            })
            .collect();
        let mut table = vec![f64::NAN; n];
        if let Some(first) = bend.iter().position(|b| *b) {
            // Once round the loop from a bend: every point has met its last bend.
            let mut d = 0.0;
            for k in 0..n {
                let i = (first + k) % n;
                d = if bend[i] { 0.0 } else { d + ds };
                table[i] = d;
            }
        }
        Self { ds, table }
    }

    /// NaN on a track without bends.
    fn at(&self, s: f64) -> f64 {
        let n = self.table.len();
        self.table[((s / self.ds).floor() as usize).min(n - 1)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_oval_has_bends_and_straights_and_a_car_on_it_is_scored_where_it_is() {
        let oval = Track::load(&mtanet_scenes::shipped_track("oval")).unwrap();
        // The oval starts half way along a 1 m straight heading +x; a 0.4 m half circle
        // follows from s = 0.5.
        let on_straight = GroundTruth {
            track_s: 0.25,
            yaw: 0.1,
            lateral_m: 0.01,
            ..Default::default()
        };
        let t = Targets::new(&oval, &[on_straight, on_straight], 0.1);
        let [_, _, heading, lateral, since] = t.values[0];
        assert!((heading - 0.1).abs() < 1e-6 && lateral == 0.01);
        // 0.75 m into the straight, and a few cm more: near its ends the window sees part of the
        // bend as straight, so a bend is a little shorter than its arc.
        assert!((0.7..0.85).contains(&since), "{since}");
        let in_bend = oval.curvature_at(0.5 + 0.2 * std::f64::consts::PI, CURVATURE_HALF_WINDOW_M);
        assert!((in_bend - 2.5).abs() < 0.15, "{in_bend}");
    }
}
