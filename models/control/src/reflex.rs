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
    /// one (2.0: closer than 1.5 on 5 of 6 unseen tracks; docs/experiments.md, "The reflex's
    /// gentle turn")...
    pub gentle: f32,
    /// ...and when a side sensor sees it alone (0, 0 and 0: no reflex, the plan alone steers).
    /// The rule's own turn: weaker, the car slips off the line at the exit of tight bends
    /// (docs/experiments.md, "The reflex at the rule's turn").
    pub strong: f32,
    /// ...and when no sensor sees it, toward the side it was last seen on (the rule's memory;
    /// 0: none). The bar has left the line, most often in a bend tighter than the plan turned.
    pub search: f32,
    /// The most forward speed (rad/s) while a side sensor sees the line alone or none does: the
    /// line is slipping away, most often at the exit of a bend taken too fast (0: no limit).
    pub strong_max_speed: f32,
}

impl Default for ReflexConfig {
    fn default() -> Self {
        Self {
            gentle: 2.0,
            strong: 6.0,
            search: 6.0,
            strong_max_speed: 5.0,
        }
    }
}

impl ReflexConfig {
    /// The turn the sensors' prediction error asks for: toward the side sensor that sees the
    /// line, or with none on, toward `last_side` (+1 left, -1 right, 0 unknown); none when the
    /// reading is the preferred one, or says nothing about the side.
    pub fn turn(&self, line: [bool; 3], last_side: f32) -> f32 {
        match line {
            [true, true, false] => self.gentle,
            [true, false, false] => self.strong,
            [false, true, true] => -self.gentle,
            [false, false, true] => -self.strong,
            [false, false, false] => self.search * last_side,
            _ => 0.0,
        }
    }

    /// `planned` with the reflex's turn added.
    pub fn apply(&self, planned: Wheels, line: [bool; 3], last_side: f32) -> Wheels {
        let d = Drive::from_wheels(planned);
        let slipping = match line {
            [true, false, false] | [false, false, true] => true,
            [false, false, false] => self.search > 0.0 && last_side != 0.0,
            _ => false,
        };
        let speed = match slipping && self.strong_max_speed > 0.0 {
            true => d.speed.min(self.strong_max_speed),
            false => d.speed,
        };
        Drive::new(speed, d.turn + self.turn(line, last_side)).wheels()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_toward_the_side_that_sees_the_line_and_slows_when_it_slips_away() {
        let r = ReflexConfig::default();
        let fast = Drive::new(10.0, 0.0).wheels();
        let centred = Drive::from_wheels(r.apply(fast, [false, true, false], 0.0));
        assert_eq!(
            (centred.speed, centred.turn),
            (10.0, 0.0),
            "preferred reading"
        );
        let left = Drive::from_wheels(r.apply(fast, [true, true, false], 0.0));
        assert!((left.turn - r.gentle).abs() < 1e-5 && left.speed == 10.0);
        let slipping = Drive::from_wheels(r.apply(fast, [false, false, true], 0.0));
        assert!((slipping.turn + r.strong).abs() < 1e-5, "{slipping:?}");
        assert!(
            (slipping.speed - r.strong_max_speed).abs() < 1e-5,
            "{slipping:?}"
        );
        let slow = Drive::new(3.0, 0.0).wheels();
        let kept = Drive::from_wheels(r.apply(slow, [true, false, false], 0.0));
        assert!(
            (kept.speed - 3.0).abs() < 1e-5,
            "a slower plan is not sped up"
        );
    }

    #[test]
    fn with_no_sensor_on_the_search_turns_toward_where_the_line_was_last_seen() {
        let r = ReflexConfig {
            search: 6.0,
            ..ReflexConfig::default()
        };
        let fast = Drive::new(10.0, -2.0).wheels();
        let left = Drive::from_wheels(r.apply(fast, [false; 3], 1.0));
        assert!((left.turn - 4.0).abs() < 1e-5, "{left:?}");
        assert!((left.speed - r.strong_max_speed).abs() < 1e-5, "{left:?}");
        let right = Drive::from_wheels(r.apply(fast, [false; 3], -1.0));
        assert!((right.turn + 8.0).abs() < 1e-5, "{right:?}");
        let unknown = Drive::from_wheels(r.apply(fast, [false; 3], 0.0));
        assert_eq!(
            (unknown.speed, unknown.turn),
            (10.0, -2.0),
            "no side known: the plan"
        );
        let none = ReflexConfig {
            search: 0.0,
            ..ReflexConfig::default()
        };
        let off = Drive::from_wheels(none.apply(fast, [false; 3], 1.0));
        assert_eq!((off.speed, off.turn), (10.0, -2.0), "search 0: the plan");
    }
}
