//! When a car must be put back at the start, from ground truth: it has been farther than
//! `lost_lateral_m` off the line for `window_s` (it sees bare floor and would record nothing
//! useful), or it has driven the wrong way round, more than `reverse_m` backwards along the
//! track over the same window (a line follower turned around follows the line backwards for
//! ever, and completes no lap).

use std::collections::VecDeque;

use crate::GroundTruth;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Fine,
    Lost,
    WrongWay,
}

#[derive(Debug, Clone)]
pub struct Referee {
    window: usize,
    lost_lateral_m: f64,
    reverse_m: f64,
    off_steps: usize,
    progress: VecDeque<f64>,
}

impl Referee {
    /// `window_s` of 0 never puts the car back; `reverse_m` of 0 ignores the direction.
    pub fn new(window_s: f64, control_period_s: f64, lost_lateral_m: f64, reverse_m: f64) -> Self {
        Self {
            window: (window_s / control_period_s).round().max(0.0) as usize,
            lost_lateral_m,
            reverse_m,
            off_steps: 0,
            progress: VecDeque::new(),
        }
    }

    /// After a control step: `truth` and the net progress along the track (`World::progress_m`).
    pub fn judge(&mut self, truth: &GroundTruth, progress_m: f64) -> Verdict {
        if self.window == 0 {
            return Verdict::Fine;
        }
        self.off_steps = if truth.lateral_m.abs() > self.lost_lateral_m {
            self.off_steps + 1
        } else {
            0
        };
        self.progress.push_back(progress_m);
        if self.progress.len() > self.window + 1 {
            self.progress.pop_front();
        }
        if self.off_steps >= self.window {
            return Verdict::Lost;
        }
        let back = self.progress.len() > self.window
            && self
                .progress
                .front()
                .is_some_and(|p0| progress_m < p0 - self.reverse_m);
        if self.reverse_m > 0.0 && back {
            return Verdict::WrongWay;
        }
        Verdict::Fine
    }

    /// The car was put back.
    pub fn reset(&mut self) {
        self.off_steps = 0;
        self.progress.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(lateral_m: f64) -> GroundTruth {
        GroundTruth {
            lateral_m,
            ..Default::default()
        }
    }

    #[test]
    fn lost_after_the_window_off_the_line_and_wrong_way_after_driving_back() {
        let mut r = Referee::new(1.0, 0.02, 0.1, 0.15);
        for k in 0..49 {
            assert_eq!(r.judge(&at(0.2), 0.0), Verdict::Fine, "step {k}");
        }
        assert_eq!(r.judge(&at(0.2), 0.0), Verdict::Lost);
        r.reset();
        // Backwards at 0.2 m/s: 0.2 m over the 1 s window.
        let mut verdict = Verdict::Fine;
        for k in 0..60 {
            verdict = r.judge(&at(0.0), -0.004 * k as f64);
            if verdict != Verdict::Fine {
                assert!(k >= 50, "not before a whole window: {k}");
                break;
            }
        }
        assert_eq!(verdict, Verdict::WrongWay);
        // Standing still or going forward never is.
        r.reset();
        for k in 0..200 {
            assert_eq!(r.judge(&at(0.0), 0.004 * k as f64), Verdict::Fine);
        }
        let mut off = Referee::new(0.0, 0.02, 0.1, 0.15);
        assert_eq!(off.judge(&at(5.0), -9.0), Verdict::Fine);
    }
}
