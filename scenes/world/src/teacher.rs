//! The teacher: the classic three-sensor line-tracer rule that drove the paper's V-REP car, plus
//! seeded exploration noise so recorded data covers more than the one perfect path.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::{CONTROL_PERIOD_S, Sensors};

/// Teacher settings (wheel speeds in rad/s).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct TeacherConfig {
    /// Both wheels' speed on a straight line.
    pub cruise: f32,
    /// How much a side sensor alone slows its wheel; more than `cruise` reverses it.
    pub turn: f32,
    /// Fraction of `turn` used when the middle sensor still sees the line too (a gentle
    /// correction: the car is only slightly off).
    pub gentle: f32,
    /// Multiple of `turn` used to search when no sensor sees the line.
    pub search: f32,
    /// Stationary standard deviation of the exploration noise added to each wheel; 0 = off.
    pub noise_std: f32,
    /// Correlation time of the noise (Ornstein-Uhlenbeck), seconds: smooth wandering rather than
    /// white jitter the car's inertia would filter out.
    pub noise_tau_s: f32,
    /// Seed of the noise; the same seed and sensors give the same commands.
    pub seed: u64,
    /// Control steps to back off when both side sensors see the line (a crossing or a car
    /// standing across the line).
    pub backoff_steps: u32,
    /// Period of `act` calls, seconds (discretises the noise).
    pub control_period_s: f64,
}

impl Default for TeacherConfig {
    fn default() -> Self {
        TeacherConfig {
            cruise: 8.0,
            turn: 10.0,
            gentle: 0.5,
            search: 1.5,
            noise_std: 0.0,
            noise_tau_s: 0.3,
            seed: 0,
            backoff_steps: 5,
            control_period_s: CONTROL_PERIOD_S,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Left,
    Middle,
    Right,
}

/// Line-tracer rule with memory of where the line was last seen.
#[derive(Debug, Clone)]
pub struct Teacher {
    cfg: TeacherConfig,
    rng: ChaCha8Rng,
    noise: [f32; 2],
    last_seen: Side,
    backoff_left: u32,
}

impl Teacher {
    pub fn new(cfg: &TeacherConfig) -> Self {
        Teacher {
            cfg: cfg.clone(),
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            noise: [0.0; 2],
            last_seen: Side::Middle,
            backoff_left: 0,
        }
    }

    /// Back to the initial state (same seed, same noise sequence).
    pub fn reset(&mut self) {
        *self = Teacher::new(&self.cfg);
    }

    /// Wheel command [left, right] in rad/s for the current sensors. Uses only what a real car
    /// has (the line sensors), never the ground truth.
    pub fn act(&mut self, s: &Sensors) -> [f32; 2] {
        self.act_on_line(s.line)
    }

    /// Remembers where the line was last seen without acting: called every step while another
    /// driver steers, a stand-in command (a missed deadline) then searches on the right side (a
    /// stale side turns the car away from the line and, in the end, around).
    pub fn observe(&mut self, line: [bool; 3]) {
        self.last_seen = match line {
            [true, _, false] => Side::Left,
            [false, _, true] => Side::Right,
            [false, true, false] => Side::Middle,
            _ => return,
        };
    }

    /// [`Teacher::act`] from the three line sensors alone (what a remote process sees in an
    /// observation message).
    pub fn act_on_line(&mut self, line: [bool; 3]) -> [f32; 2] {
        let base = self.rule(line);
        let n = self.next_noise();
        [base[0] + n[0], base[1] + n[1]]
    }

    fn rule(&mut self, line: [bool; 3]) -> [f32; 2] {
        let (c, t) = (self.cfg.cruise, self.cfg.turn);
        if self.backoff_left > 0 {
            self.backoff_left -= 1;
            return [-0.5 * c, -0.5 * c];
        }
        // Slowing the wheel on the side where the line is turns the car towards it.
        let left_turn = |amount: f32| [c - amount, c];
        let right_turn = |amount: f32| [c, c - amount];
        self.observe(line);
        match line {
            [true, _, true] => {
                self.backoff_left = self.cfg.backoff_steps.saturating_sub(1);
                [-0.5 * c, -0.5 * c]
            }
            [true, true, false] => left_turn(self.cfg.gentle * t),
            [true, false, false] => left_turn(t),
            [false, true, true] => right_turn(self.cfg.gentle * t),
            [false, false, true] => right_turn(t),
            [false, true, false] => [c, c],
            // Lost the line: search towards where it was last seen, or keep going.
            [false, false, false] => match self.last_seen {
                Side::Left => left_turn(self.cfg.search * t),
                Side::Right => right_turn(self.cfg.search * t),
                Side::Middle => [c, c],
            },
        }
    }

    /// One step of an Ornstein-Uhlenbeck process per wheel with stationary std `noise_std`.
    fn next_noise(&mut self) -> [f32; 2] {
        if self.cfg.noise_std <= 0.0 {
            return [0.0; 2];
        }
        let tau = self.cfg.noise_tau_s.max(1e-3) as f64;
        let a = (-self.cfg.control_period_s / tau).exp();
        let b = (1.0 - a * a).sqrt() * self.cfg.noise_std as f64;
        for k in 0..2 {
            let z = standard_normal(&mut self.rng);
            self.noise[k] = (a * self.noise[k] as f64 + b * z) as f32;
        }
        self.noise
    }
}

/// Box-Muller; avoids a rand_distr dependency for one distribution.
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    // 1 - u in (0, 1] keeps ln finite.
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
