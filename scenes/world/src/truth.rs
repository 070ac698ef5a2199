//! Ground truth for evaluation: pose, progress along the track, lateral error, laps.

use serde::Serialize;

use mtanet_track::Track;

/// What really happened, for evaluation only (the model never sees it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct GroundTruth {
    /// Car origin (axle midpoint) in the world, metres.
    pub x: f64,
    pub y: f64,
    /// Heading, radians in (-pi, pi], 0 = world +x, counter-clockwise positive.
    pub yaw: f64,
    /// Arc length along the track of the projection of the sensor-bar centre, in [0, length).
    pub track_s: f64,
    /// Signed distance of the sensor-bar centre from the line, metres: positive when the line is
    /// to the car's left (the car should steer left), negative when it is to the right.
    pub lateral_m: f64,
    /// Completed laps since the start/reset: forward progress along the track of a whole track
    /// length per lap. Backing up and driving forward again does not count twice.
    pub laps: u32,
    /// |lateral_m| < half the line width: the middle line sensor is over the line.
    pub on_line: bool,
}

/// Signed lateral offset of the line from a point, in the frame of a car heading `yaw`.
pub(crate) fn lateral(track: &Track, bar: [f64; 2], yaw: f64) -> (f64, f64) {
    let p = track.project(bar);
    let d = [p.point[0] - bar[0], p.point[1] - bar[1]];
    let left = [-yaw.sin(), yaw.cos()];
    let side = d[0] * left[0] + d[1] * left[1];
    // Magnitude is the true distance; the sign says which side of the car the line is on.
    let lat = if side < 0.0 { -p.distance } else { p.distance };
    (p.s, lat)
}

/// Unwrapped progress along the track. Laps are counted on net forward progress, so reversing
/// across the start and driving over it again cannot add a lap.
#[derive(Debug, Clone)]
pub(crate) struct LapCounter {
    length: f64,
    last_s: f64,
    progress: f64,
    laps: u32,
}

impl LapCounter {
    pub fn new(length: f64, s: f64) -> Self {
        LapCounter {
            length,
            last_s: s,
            progress: 0.0,
            laps: 0,
        }
    }

    /// Adds the move from the last position to `s`, taking the short way round the loop (a car
    /// moves far less than half a track in one control period).
    pub fn update(&mut self, s: f64) {
        let half = self.length / 2.0;
        let d = (s - self.last_s + half).rem_euclid(self.length) - half;
        self.progress += d;
        self.last_s = s;
        let completed = (self.progress / self.length).floor();
        if completed > self.laps as f64 {
            self.laps = completed as u32;
        }
    }

    /// After a teleport: continue from `s` without counting the jump.
    pub fn reanchor(&mut self, s: f64) {
        self.last_s = s;
    }

    pub fn laps(&self) -> u32 {
        self.laps
    }

    /// Net distance driven along the track since the start, metres.
    pub fn progress(&self) -> f64 {
        self.progress
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laps_count_forward_progress_only() {
        let len = 10.0;
        let mut c = LapCounter::new(len, 9.5);
        // Forward almost a lap, across the wrap.
        for k in 1..=90 {
            c.update((9.5 + 0.1 * k as f64).rem_euclid(len));
        }
        assert_eq!(c.laps(), 0);
        for k in 91..=101 {
            c.update((9.5 + 0.1 * k as f64).rem_euclid(len));
        }
        assert_eq!(c.laps(), 1);
        // Back up 0.5 m across the start, and forward again: still one lap.
        let s0 = (9.5 + 10.1_f64).rem_euclid(len);
        for k in 1..=5 {
            c.update((s0 - 0.1 * k as f64).rem_euclid(len));
        }
        for k in -4..=5 {
            c.update((s0 - 0.5 + 0.1 * (k + 5) as f64).rem_euclid(len));
        }
        assert_eq!(c.laps(), 1);
        assert!((c.progress() - 10.6).abs() < 1e-9, "{}", c.progress());
    }

    #[test]
    fn reverse_driving_never_counts() {
        let mut c = LapCounter::new(10.0, 0.0);
        for k in 1..=300 {
            c.update((-0.1 * k as f64).rem_euclid(10.0));
        }
        assert_eq!(c.laps(), 0);
    }
}
