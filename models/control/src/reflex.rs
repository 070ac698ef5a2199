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
    /// Turn added per second (rad/s per s) that the line slips away one way (a side sensor
    /// alone or none sees it), kept while the sensors still ask for a turn that way: a bend
    /// sharper than any the model learnt, where its plans under-turn, gets a growing turn, as
    /// an integral term removes a controller's steady error (20 with `ramp_max` 4: closer on 3
    /// of 4 unseen tracks, 0 fallbacks; docs/experiments.md, "The reflex's ramp"). 0: none.
    pub ramp: f32,
    /// The most the ramp adds, rad/s.
    pub ramp_max: f32,
}

impl Default for ReflexConfig {
    fn default() -> Self {
        Self {
            gentle: 2.0,
            strong: 6.0,
            search: 6.0,
            strong_max_speed: 5.0,
            ramp: 20.0,
            ramp_max: 4.0,
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

    /// `planned` with the reflex's turn and `extra` (the ramp's, toward the same side) added;
    /// [`Reflex`] keeps the ramp.
    pub fn apply(&self, planned: Wheels, line: [bool; 3], last_side: f32, extra: f32) -> Wheels {
        let d = Drive::from_wheels(planned);
        let slipping =
            slipping(line) && (line != [false; 3] || self.search > 0.0 && last_side != 0.0);
        let speed = match slipping && self.strong_max_speed > 0.0 {
            true => d.speed.min(self.strong_max_speed),
            false => d.speed,
        };
        let turn = self.turn(line, last_side);
        Drive::new(speed, d.turn + turn + extra * sign(turn)).wheels()
    }
}

/// A side sensor sees the line alone, or none sees it: the line is slipping from under the bar.
fn slipping(line: [bool; 3]) -> bool {
    matches!(
        line,
        [true, false, false] | [false, false, true] | [false, false, false]
    )
}

/// -1, 0 or +1 (`f32::signum` gives 1 for 0).
fn sign(x: f32) -> f32 {
    if x == 0.0 { 0.0 } else { x.signum() }
}

/// The reflex with its memory: how long the sensors have asked for a turn the same way (the
/// ramp's integral). One per car, reset with each episode.
#[derive(Debug, Clone)]
pub struct Reflex {
    cfg: ReflexConfig,
    period_s: f32,
    side: f32,
    held_s: f32,
}

impl Reflex {
    pub fn new(cfg: &ReflexConfig, control_period_s: f32) -> Self {
        Self {
            cfg: cfg.clone(),
            period_s: control_period_s,
            side: 0.0,
            held_s: 0.0,
        }
    }

    pub fn reset(&mut self) {
        (self.side, self.held_s) = (0.0, 0.0);
    }

    /// This step's command: `planned` with the reflex's turn, the ramp included.
    pub fn apply(&mut self, planned: Wheels, line: [bool; 3], last_side: f32) -> Wheels {
        let side = sign(self.cfg.turn(line, last_side));
        if side == 0.0 || side != self.side {
            (self.side, self.held_s) = (side, 0.0);
        } else if slipping(line) {
            // Only the line slipping away grows it: the gentle turn's own wobble on a
            // straight does not (it would swing the car).
            self.held_s += self.period_s;
        }
        let extra = (self.cfg.ramp * self.held_s).min(self.cfg.ramp_max);
        self.cfg.apply(planned, line, last_side, extra)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_toward_the_side_that_sees_the_line_and_slows_when_it_slips_away() {
        let r = ReflexConfig::default();
        let fast = Drive::new(10.0, 0.0).wheels();
        let centred = Drive::from_wheels(r.apply(fast, [false, true, false], 0.0, 0.0));
        assert_eq!(
            (centred.speed, centred.turn),
            (10.0, 0.0),
            "preferred reading"
        );
        let left = Drive::from_wheels(r.apply(fast, [true, true, false], 0.0, 0.0));
        assert!((left.turn - r.gentle).abs() < 1e-5 && left.speed == 10.0);
        let slipping = Drive::from_wheels(r.apply(fast, [false, false, true], 0.0, 0.0));
        assert!((slipping.turn + r.strong).abs() < 1e-5, "{slipping:?}");
        assert!(
            (slipping.speed - r.strong_max_speed).abs() < 1e-5,
            "{slipping:?}"
        );
        let slow = Drive::new(3.0, 0.0).wheels();
        let kept = Drive::from_wheels(r.apply(slow, [true, false, false], 0.0, 0.0));
        assert!(
            (kept.speed - 3.0).abs() < 1e-5,
            "a slower plan is not sped up"
        );
    }

    #[test]
    fn the_ramp_grows_while_the_line_slips_away_one_way_and_ends_when_it_is_centred() {
        let cfg = ReflexConfig {
            ramp: 10.0,
            ramp_max: 3.0,
            ..ReflexConfig::default()
        };
        let mut r = Reflex::new(&cfg, 0.02);
        let straight = Drive::new(4.0, 0.0).wheels();
        let turn = |r: &mut Reflex, line| Drive::from_wheels(r.apply(straight, line, 0.0)).turn;
        let (slip, drift) = ([true, false, false], [true, true, false]);
        assert!((turn(&mut r, drift) - cfg.gentle).abs() < 1e-5);
        for _ in 0..20 {
            let t = turn(&mut r, drift);
            assert!(
                (t - cfg.gentle).abs() < 1e-5,
                "drifting alone: no ramp ({t})"
            );
        }
        for step in 1..10 {
            let t = turn(&mut r, slip);
            let want = cfg.strong + 10.0 * 0.02 * step as f32;
            assert!((t - want).abs() < 1e-4, "step {step}: {t} vs {want}");
        }
        let kept = turn(&mut r, drift);
        let want = cfg.gentle + 10.0 * 0.02 * 9.0;
        assert!(
            (kept - want).abs() < 1e-4,
            "kept, not grown, once back to a drift: {kept}"
        );
        let mut last = kept;
        for _ in 0..100 {
            last = turn(&mut r, slip);
        }
        assert!(
            (last - cfg.strong - 3.0).abs() < 1e-4,
            "capped at ramp_max: {last}"
        );
        let right = turn(&mut r, [false, false, true]);
        assert!(
            (right + cfg.strong).abs() < 1e-5,
            "the other way starts afresh: {right}"
        );
        assert_eq!(turn(&mut r, [false, true, false]), 0.0, "centred: none");
        let again = turn(&mut r, slip);
        assert!(
            (again - cfg.strong).abs() < 1e-5,
            "a centred step ends it: {again}"
        );
        let none = ReflexConfig {
            ramp: 0.0,
            ..cfg.clone()
        };
        let mut off = Reflex::new(&none, 0.02);
        for _ in 0..50 {
            last = turn(&mut off, slip);
        }
        assert!((last - cfg.strong).abs() < 1e-5, "ramp 0: none");
    }

    #[test]
    fn with_no_sensor_on_the_search_turns_toward_where_the_line_was_last_seen() {
        let r = ReflexConfig {
            search: 6.0,
            ..ReflexConfig::default()
        };
        let fast = Drive::new(10.0, -2.0).wheels();
        let left = Drive::from_wheels(r.apply(fast, [false; 3], 1.0, 0.0));
        assert!((left.turn - 4.0).abs() < 1e-5, "{left:?}");
        assert!((left.speed - r.strong_max_speed).abs() < 1e-5, "{left:?}");
        let right = Drive::from_wheels(r.apply(fast, [false; 3], -1.0, 0.0));
        assert!((right.turn + 8.0).abs() < 1e-5, "{right:?}");
        let unknown = Drive::from_wheels(r.apply(fast, [false; 3], 0.0, 0.0));
        assert_eq!(
            (unknown.speed, unknown.turn),
            (10.0, -2.0),
            "no side known: the plan"
        );
        let none = ReflexConfig {
            search: 0.0,
            ..ReflexConfig::default()
        };
        let off = Drive::from_wheels(none.apply(fast, [false; 3], 1.0, 0.0));
        assert_eq!((off.speed, off.turn), (10.0, -2.0), "search 0: the plan");
    }
}
