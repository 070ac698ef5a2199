//! The reflex arc of active inference: the line sensors' prediction error, against the
//! preferred reading (only the middle sensor on), turns the car at the control rate, on top of
//! the command the plan holds for its segment. The plan (through the learnt model, 0.1 s
//! segments) says where to go; the reflex fulfils the preferred sensation between two plans.

use serde::{Deserialize, Serialize};

use crate::drive::{Drive, Wheels};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReflexConfig {
    /// Turn added (rad/s, toward the line) when a side sensor sees the line with the middle
    /// one...
    pub gentle: f32,
    /// ...and when a side sensor sees it alone (0 and 0: no reflex, the plan alone steers).
    pub strong: f32,
}

impl Default for ReflexConfig {
    fn default() -> Self {
        Self {
            gentle: 1.5,
            strong: 4.0,
        }
    }
}

impl ReflexConfig {
    /// The turn the sensors' prediction error asks for: toward the side sensor that sees the
    /// line; none when the reading is the preferred one, or says nothing about the side.
    pub fn turn(&self, line: [bool; 3]) -> f32 {
        match line {
            [true, true, false] => self.gentle,
            [true, false, false] => self.strong,
            [false, true, true] => -self.gentle,
            [false, false, true] => -self.strong,
            _ => 0.0,
        }
    }

    /// `planned` with the reflex's turn added.
    pub fn apply(&self, planned: Wheels, line: [bool; 3]) -> Wheels {
        let d = Drive::from_wheels(planned);
        Drive::new(d.speed, d.turn + self.turn(line)).wheels()
    }
}
