//! How the fallback finds a line it lost: it drives backwards until both wheels have turned back
//! by what they turned since the line was last in sight (a line sensor on, or the line in the
//! near half of the camera's view: the agent's test for a lost line), which brings the car back
//! to about where it left the line, facing the way it was going (the heading is the difference
//! of the wheel angles, so it comes back exactly; the position within a few centimetres), and
//! the reactive rule follows the line forward from there. The wheel angles come from the
//! measured wheel velocities, so the servo's lag does not matter (replaying the commands
//! backwards left the heading off by a third of the turn the car had made). The camera counts:
//! a car drifting slowly off a straight, its camera following the line beside it for seconds
//! after the sensors lost it, would otherwise back up all that way (and be put back for driving
//! the wrong way round); so it backs up the half second the fallback waited, and the rule's
//! search turns to the side the sensors last saw the line on, meeting it at a shallow angle.
//! Only when the way back is unknown (out of sight longer than the memory, or more than a few
//! frames missed meanwhile) does the rule's own search drive first: turning toward the side the
//! line was last seen on, which circles, finds nothing from more than about 10 cm away, and
//! crosses the line at any heading (half the time it then follows the line backwards). At a
//! bend's exit the search would find the line sooner than the way back, which backs out of the
//! bend first; but a search that meets the line at a steep angle follows it either way, so it
//! never goes first (docs/measurements.md).

use crate::drive::Wheels;

/// Wheel angle (rad) left to undo at which the way back is done: about 5 mm of travel.
const DONE_RAD: f32 = 0.2;
/// Time constant of the way back's last stretch (s): it slows down as the angles close.
const SETTLE_S: f32 = 0.1;
/// Heading (rad) per rad of difference between the wheels' angles: the wheel radius over the
/// distance between the wheels (27 mm over 100 mm for the car `mtanet_scenes::car` builds;
/// `models/eval/tests/recovery.rs` checks they agree).
pub const HEADING_PER_WHEEL_RAD: f32 = 0.27;
/// Heading left to undo (rad) at which a line sensor seeing the line ends the way back: the car
/// is back at the line facing forward enough for the rule to follow it forward (at a bend's exit
/// that is after a few cm backwards).
const HEADING_DONE_RAD: f32 = 0.5;
/// Frames missed (a busy or stopped predictor) across which the wheel angles are still
/// interpolated; after a longer gap the way back is unknown and the rule searches.
const MAX_GAP_STEPS: u64 = 5;

#[derive(Debug, Clone)]
pub struct Recovery {
    period_s: f32,
    /// Off the line (or on the way back) for longer than this many steps: no way back.
    max_ticks: u32,
    /// Fastest wheel speed on the way back, rad/s.
    speed: f32,
    /// Wheel angles turned since the line was last in sight, rad.
    turned: [f32; 2],
    /// The previous frame's step and measured wheel velocities.
    last: Option<(u64, Wheels)>,
    ticks: u32,
    state: State,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Counting what the wheels turn off the line.
    Remembering,
    /// Undoing it until the heading is nearly the one the car had on the line and a sensor sees
    /// the line (stopping at the first sensor that sees it, whatever the heading, can leave the
    /// car across the line, and the rule may then follow it either way), or all is undone.
    Retracing,
    /// Done, or off the line too long: the rule searches until the line is found.
    Searching,
}

impl Recovery {
    /// Goes back after up to `memory_s` off the line (0: never), at wheel speeds up to `speed`.
    pub fn new(memory_s: f32, speed: f32, control_period_s: f32) -> Self {
        Self {
            period_s: control_period_s,
            max_ticks: (memory_s / control_period_s).round().max(0.0) as u32,
            speed,
            turned: [0.0; 2],
            last: None,
            ticks: 0,
            state: State::Remembering,
        }
    }

    /// Every control step, whoever drives: the frame's step (the simulator's count), whether the
    /// line is in sight (a line sensor, or the camera) and the wheel velocities measured at it
    /// (rad/s).
    pub fn observe(&mut self, step: u64, in_sight: bool, measured: Wheels) {
        match self.last.replace((step, measured)) {
            Some((s0, before)) if step >= s0 && step - s0 <= MAX_GAP_STEPS => {
                let dt = (step - s0) as f32 * self.period_s;
                for (t, (a, b)) in self.turned.iter_mut().zip(before.iter().zip(measured)) {
                    *t += 0.5 * (a + b) * dt;
                }
            }
            Some(_) if !in_sight => self.state = State::Searching,
            _ => {}
        }
        match self.state {
            State::Remembering | State::Searching if in_sight => self.restart(),
            State::Remembering | State::Retracing => self.ticks += 1,
            State::Searching => {}
        }
    }

    /// The fallback's command while it goes back; `None` on the line, once back, or when there
    /// is no way back (the rule drives then).
    pub fn retrace(&mut self, line: [bool; 3]) -> Option<Wheels> {
        let left = self.turned[0].abs().max(self.turned[1].abs());
        match self.state {
            State::Searching => None,
            State::Remembering if line.contains(&true) || left <= DONE_RAD => None,
            State::Remembering if self.ticks > self.max_ticks => self.give_up(),
            State::Retracing
                if left <= DONE_RAD
                    || self.ticks > 2 * self.max_ticks
                    || (line.contains(&true) && self.heading_left() <= HEADING_DONE_RAD) =>
            {
                self.give_up()
            }
            _ => {
                if self.state == State::Remembering {
                    self.state = State::Retracing;
                    self.ticks = 0;
                }
                let gain = (1.0 / SETTLE_S).min(self.speed / left);
                Some(self.turned.map(|t| -gain * t))
            }
        }
    }

    /// Heading still to undo, rad.
    fn heading_left(&self) -> f32 {
        (self.turned[1] - self.turned[0]).abs() * HEADING_PER_WHEEL_RAD
    }

    /// Back, or no way back: the rule drives until the line is found.
    fn give_up(&mut self) -> Option<Wheels> {
        self.state = State::Searching;
        None
    }

    /// The fallback is over (or a new episode began): count afresh.
    pub fn reset(&mut self) {
        self.restart();
        self.last = None;
    }

    fn restart(&mut self) {
        self.turned = [0.0; 2];
        self.ticks = 0;
        self.state = State::Remembering;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OFF: [bool; 3] = [false; 3];
    const ON: [bool; 3] = [false, true, false];

    /// An ideal drive, one frame per step: the wheels turn at the command at once.
    fn drive(r: &mut Recovery, line: [bool; 3], w: Wheels) {
        let step = r.last.map_or(0, |(s, _)| s + 1);
        r.observe(step, line.contains(&true), w);
    }

    #[test]
    fn turns_both_wheels_back_by_what_they_turned_off_the_line_and_then_stops() {
        let mut r = Recovery::new(3.0, 8.0, 0.02);
        drive(&mut r, ON, [8.0, 8.0]);
        drive(&mut r, ON, [8.0, 8.0]); // on the line: nothing to undo
        assert_eq!(r.retrace(ON), None);
        for _ in 0..25 {
            drive(&mut r, OFF, [8.0, 2.0]);
        }
        // 0.5 s at ~[8, 2] rad/s: ~4 and ~1 rad to undo, in that ratio, at most 8 rad/s.
        let w = r.retrace(OFF).unwrap();
        assert!(w[0] < 0.0 && w[1] < 0.0, "{w:?}");
        assert!((w[0] / w[1] - 4.0).abs() < 0.3, "{w:?}");
        assert!((w[0] + 8.0).abs() < 1e-4, "{w:?}");
        let mut steps = 0;
        let mut back = Some(w);
        while let Some(w) = back {
            // A sensor crossing the line with the car still turned away does not stop it.
            let line = if steps == 3 { ON } else { OFF };
            drive(&mut r, line, w);
            back = r.retrace(line);
            steps += 1;
            assert!(steps < 200, "never back");
        }
        assert!(r.turned.iter().all(|t| t.abs() <= DONE_RAD), "{r:?}");
        assert!(steps > 10, "{steps}");
        // Back and no line: the rule searches, and its turning is not undone...
        drive(&mut r, OFF, [2.0, 14.0]);
        assert_eq!(r.retrace(OFF), None);
        // ...until the line is found: a new loss counts from there.
        drive(&mut r, ON, [8.0, 8.0]);
        for _ in 0..5 {
            drive(&mut r, OFF, [8.0, 8.0]);
        }
        assert!(r.retrace(OFF).is_some());
        r.reset();
        assert_eq!(r.retrace(OFF), None);
    }

    #[test]
    fn a_sensor_on_the_line_ends_the_way_back_once_the_heading_is_nearly_back() {
        let mut r = Recovery::new(3.0, 8.0, 0.02);
        drive(&mut r, ON, [8.0, 8.0]);
        // ~0.4 s of a turn of 8 rad/s difference: 0.84 rad of heading.
        for _ in 0..20 {
            drive(&mut r, OFF, [4.0, 12.0]);
        }
        assert!(
            (r.heading_left() - 0.842).abs() < 0.01,
            "{}",
            r.heading_left()
        );
        let w = r.retrace(OFF).unwrap();
        drive(&mut r, ON, w); // still ~0.8 rad turned away: go on
        let mut w = r.retrace(ON).expect("heading not back yet");
        let mut steps = 0;
        while r.heading_left() > HEADING_DONE_RAD {
            drive(&mut r, OFF, w);
            w = r.retrace(OFF).unwrap();
            steps += 1;
            assert!(steps < 100);
        }
        drive(&mut r, ON, w);
        assert_eq!(
            r.retrace(ON),
            None,
            "facing forward at the line: the rule follows it"
        );
    }

    #[test]
    fn a_line_still_in_the_cameras_view_counts_as_in_sight() {
        let mut r = Recovery::new(3.0, 8.0, 0.02);
        // 2 s beside the line, the sensors off it and the camera still seeing it, then 0.5 s
        // with the line out of sight: only the last 0.5 s is undone.
        for step in 0..100 {
            r.observe(step, true, [8.0, 8.0]);
        }
        for step in 100..125 {
            r.observe(step, false, [8.0, 8.0]);
        }
        assert!((r.turned[0] - 8.0 * 25.0 * 0.02).abs() < 1e-4, "{r:?}");
        assert!(r.retrace(OFF).is_some());
    }

    #[test]
    fn no_way_back_after_longer_than_the_memory() {
        let mut r = Recovery::new(0.1, 8.0, 0.02); // 5 steps
        drive(&mut r, ON, [8.0, 8.0]);
        for _ in 0..6 {
            drive(&mut r, OFF, [8.0, 8.0]);
        }
        assert_eq!(r.retrace(OFF), None);
        let mut never = Recovery::new(0.0, 8.0, 0.02);
        drive(&mut never, OFF, [8.0, 8.0]);
        assert_eq!(never.retrace(OFF), None);
    }

    #[test]
    fn a_few_missed_frames_are_bridged_and_a_long_gap_gives_the_way_back_up() {
        let mut r = Recovery::new(3.0, 8.0, 0.02);
        r.observe(10, true, [8.0, 8.0]);
        r.observe(11, false, [8.0, 8.0]);
        r.observe(14, false, [8.0, 8.0]); // two frames missed
        assert!((r.turned[0] - 8.0 * 4.0 * 0.02).abs() < 1e-5, "{r:?}");
        assert!(r.retrace(OFF).is_some());
        // A predictor stopped for a second: where it went meanwhile is unknown.
        r.observe(64, false, [-8.0, -8.0]);
        assert_eq!(r.retrace(OFF), None);
        // The line found again, a loss counts afresh.
        r.observe(65, true, [8.0, 8.0]);
        r.observe(66, false, [8.0, 8.0]);
        assert_eq!(r.retrace(OFF), None, "5 mm off: nothing to undo yet");
        r.observe(67, false, [8.0, 8.0]);
        assert!(r.retrace(OFF).is_some());
    }
}
