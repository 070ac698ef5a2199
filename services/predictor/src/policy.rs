//! Policies turn an observation into wheel velocities.

use mtanet_ipc::{CommandSource, Observation};

use crate::config::PredictorConfig;

/// The fallback before any weights exist: steer toward the side sensor that sees the line.
/// Deliberately simple; it only has to keep the car near the line while data accumulates.
#[derive(Debug, Clone)]
pub struct Reactive {
    cruise: f32,
    turn: f32,
    last_side: f32,
}

impl Reactive {
    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            cruise: cfg.cruise,
            turn: cfg.turn,
            last_side: 0.0,
        }
    }

    pub fn act(&mut self, obs: &Observation) -> ([f32; 2], CommandSource) {
        let [l, m, r] = obs.line_sensors.map(|v| v != 0);
        // +1: turn left, -1: turn right.
        let side = match (l, m, r) {
            (true, _, false) => 1.0,
            (false, _, true) => -1.0,
            (false, false, false) => self.last_side,
            _ => 0.0,
        };
        if side != 0.0 {
            self.last_side = side;
        }
        let (c, t) = (self.cruise, self.turn * side);
        ([c - t, c + t], CommandSource::Reactive)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(line: [u8; 3]) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.line_sensors = line;
        o
    }

    #[test]
    fn turns_toward_the_line() {
        let mut p = Reactive::new(&PredictorConfig::default());
        let ([l, r], _) = p.act(&obs([1, 0, 0]));
        assert!(r > l, "line on the left must turn left: {l} {r}");
        let ([l, r], _) = p.act(&obs([0, 0, 1]));
        assert!(l > r, "line on the right must turn right: {l} {r}");
        let ([l, r], _) = p.act(&obs([0, 1, 0]));
        assert_eq!(l, r);
        // Lost: keep turning toward where the line was last seen (right).
        let ([l, r], _) = p.act(&obs([0, 0, 0]));
        assert!(l > r);
    }
}
