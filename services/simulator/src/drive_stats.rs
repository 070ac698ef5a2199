//! How well the car drove, from ground truth: laps and lateral error. Shared by the standalone
//! report and the service summary.

use mtanet_scenes::GroundTruth;
pub use mtanet_summaries::simulator::LateralError;

#[derive(Debug, Default, Clone)]
pub struct DriveStats {
    steps: u64,
    sum_abs_lateral: f64,
    max_abs_lateral: f64,
    off_line_steps: u64,
    laps: u32,
    laps_before: u32,
}

impl DriveStats {
    pub fn record(&mut self, truth: &GroundTruth) {
        let lat = truth.lateral_m.abs();
        self.steps += 1;
        self.sum_abs_lateral += lat;
        self.max_abs_lateral = self.max_abs_lateral.max(lat);
        self.off_line_steps += u64::from(!truth.on_line);
        self.laps = self.laps_before + truth.laps;
    }

    /// The world was reset: its lap counter restarts, the total keeps counting.
    pub fn end_episode(&mut self) {
        self.laps_before = self.laps;
    }

    /// Completed laps over all episodes.
    pub fn laps(&self) -> u32 {
        self.laps
    }

    pub fn lateral(&self) -> LateralError {
        LateralError {
            mean: if self.steps == 0 {
                0.0
            } else {
                self.sum_abs_lateral / self.steps as f64
            },
            max: self.max_abs_lateral,
        }
    }

    /// Fraction of steps with the sensor bar's centre over the line.
    pub fn on_line_fraction(&self) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            1.0 - self.off_line_steps as f64 / self.steps as f64
        }
    }
}
