//! Wheel commands as the planner thinks of them: a forward speed and a turn rate.

use serde::{Deserialize, Serialize};

/// Wheel velocities `[left, right]`, rad/s: what the simulator applies and the model is
/// conditioned on.
pub type Wheels = [f32; 2];

/// A command as forward speed and turn: wheels = `[speed - turn, speed + turn]` (rad/s), so a
/// positive turn turns left.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Drive {
    pub speed: f32,
    pub turn: f32,
}

impl Drive {
    pub const STOP: Drive = Drive {
        speed: 0.0,
        turn: 0.0,
    };

    pub fn new(speed: f32, turn: f32) -> Self {
        Self { speed, turn }
    }

    pub fn wheels(self) -> Wheels {
        [self.speed - self.turn, self.speed + self.turn]
    }

    pub fn from_wheels(w: Wheels) -> Self {
        Self {
            speed: 0.5 * (w[0] + w[1]),
            turn: 0.5 * (w[1] - w[0]),
        }
    }
}

/// The mean of several wheel commands (a model step spans `frame_skip` control steps; its action
/// is the mean command over them, which is exact when the command was held).
pub fn mean_wheels(cmds: &[Wheels]) -> Wheels {
    if cmds.is_empty() {
        return [0.0; 2];
    }
    let n = cmds.len() as f32;
    let (l, r) = cmds
        .iter()
        .fold((0.0, 0.0), |(l, r), c| (l + c[0], r + c[1]));
    [l / n, r / n]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_and_turn_round_trip_through_wheels() {
        let d = Drive::new(8.0, 2.0);
        assert_eq!(
            d.wheels(),
            [6.0, 10.0],
            "positive turn: right wheel faster, turns left"
        );
        assert_eq!(Drive::from_wheels(d.wheels()), d);
        assert_eq!(mean_wheels(&[[1.0, 2.0], [3.0, 6.0]]), [2.0, 4.0]);
        assert_eq!(mean_wheels(&[]), [0.0, 0.0]);
    }
}
