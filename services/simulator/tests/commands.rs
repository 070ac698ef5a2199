//! What the simulator does with the commands it gets, over real iceoryx2: non-finite ones are
//! rejected and counted, and a car steered off the line is put back as a new episode.

mod common;

use mtanet_scenes::{Teacher, TeacherConfig};
use mtanet_simulator::config::{Mode, SimulatorConfig};

#[test]
fn non_finite_commands_are_rejected_counted_and_survived() {
    let cfg = SimulatorConfig {
        mode: Mode::Lockstep,
        max_steps: 200,
        wait_for_peers_s: 20.0,
        ..Default::default()
    };
    // Every 4th command is poisoned, alternating NaN and +inf.
    let d = common::drive("nan", cfg, |o| match o.step % 8 {
        3 => [f32::NAN, 5.0],
        7 => [5.0, f32::INFINITY],
        _ => [6.0, 6.0],
    });
    assert_eq!(d.summary.steps, 200);
    assert_eq!(d.summary.commands_received, 200, "{:?}", d.summary);
    assert_eq!(d.summary.rejected_commands, 50, "{:?}", d.summary);
    // Driving straight at 6 rad/s for 4 s: it moved forward despite the poison.
    assert!(
        d.truth.track_s > 0.5,
        "car did not keep driving: {:?}",
        d.truth
    );
}

#[test]
fn a_lost_car_is_put_back_as_a_new_episode() {
    let cfg = SimulatorConfig {
        mode: Mode::Lockstep,
        max_steps: 600,
        wait_for_peers_s: 20.0,
        reset_after_lost_s: 1.0,
        replay: true,
        ..Default::default()
    };
    // Episode 0: veer off to the right for good. Later episodes: follow the line like the teacher.
    let mut follower = Teacher::new(&TeacherConfig::default());
    let d = common::drive("lost", cfg, |o| {
        if o.episode == 0 {
            [12.0, 6.0]
        } else {
            follower.act_on_line(o.line_sensors.map(|v| v != 0))
        }
    });
    assert!(d.summary.resets >= 1, "{:?}", d.summary);
    let first_new = d
        .episodes
        .iter()
        .position(|&e| e == 1)
        .expect("an observation of episode 1");
    assert!(d.episodes[..first_new].iter().all(|&e| e == 0));
    assert!(
        d.episodes[first_new..].iter().all(|&e| e == 1),
        "one reset only: following the line keeps the car on it"
    );
    // Lost means > 0.1 m off for 1 s: the reset cannot come before that.
    assert!(first_new > 50, "reset after {first_new} steps");
    assert!(
        d.truth.lateral_m.abs() < 0.1,
        "back near the line after the reset: {:?}",
        d.truth
    );
}

/// The action the model learns from is the command the planner chooses: each replay step and
/// each observation carry the command applied from the previous frame to this one (not the
/// measured wheel speed, which lags it), with who decided it.
#[test]
fn replay_and_observations_carry_the_applied_command_and_its_source() {
    use mtanet_ipc::CommandSource;
    let cfg = SimulatorConfig {
        mode: Mode::Lockstep,
        max_steps: 100,
        wait_for_peers_s: 20.0,
        replay_linger_s: 0.5,
        ..Default::default()
    };
    let cmd_of = |step: u64| [4.0 + (step % 7) as f32, 6.0 - (step % 3) as f32];
    let src_of = |step: u64| {
        if step % 5 == 0 {
            CommandSource::Exploration
        } else {
            CommandSource::ActiveInference
        }
    };
    let d = common::drive_with("act", cfg, |o| (cmd_of(o.step), src_of(o.step)));
    assert_eq!(d.chunks.len(), 5, "{} chunks", d.chunks.len());
    for c in &d.chunks {
        for i in 0..c.len as usize {
            let step = c.first_step + i as u64;
            let (want, src) = if step == 0 {
                ([0.0, 0.0], CommandSource::Teacher) // the reset's zero command led to frame 0
            } else {
                (cmd_of(step - 1), src_of(step - 1))
            };
            assert_eq!(c.actions[i], want, "step {step}");
            assert_eq!(c.sources[i], src as u8, "step {step}");
        }
    }
    for o in &d.observations[1..] {
        assert_eq!(o.command, cmd_of(o.step - 1), "step {}", o.step);
        assert_eq!(o.lockstep, 1);
        assert_ne!(
            o.wheel_velocity, o.command,
            "the measured speed lags: step {}",
            o.step
        );
    }
    let s = &d.summary.control;
    assert_eq!(s.steps["exploration"], 20);
    assert_eq!(s.steps["active_inference"], 80);
    assert!((s.exploration_fraction - 0.2).abs() < 1e-9);
}

/// Real time, a predictor that stops answering for 30 steps after a command carrying 3 segments
/// of 5 steps: the car follows that plan to its end (counted as `plan_followed`, driven by the
/// plan's source), and only the steps after it are missed.
#[test]
fn without_commands_the_car_follows_the_last_plan_until_it_runs_out() {
    use mtanet_ipc::CommandSource;
    let cfg = SimulatorConfig {
        mode: Mode::Realtime,
        max_steps: 120,
        wait_for_peers_s: 20.0,
        ..Default::default()
    };
    let plan = [[5.0, 5.5], [6.0, 6.5], [7.0, 7.5]];
    let silent = 40..70;
    let d = common::drive_script("plan", cfg, |o, c| {
        c.wheel_velocity = [5.0, 5.0];
        c.source = CommandSource::ActiveInference as u32;
        c.set_plan(o.step, 5, &plan);
        !silent.contains(&o.step)
    });
    let s = &d.summary;
    // Step 39's plan covers steps 39..54: 14 silent steps follow it, 16 are missed. A late
    // answer (a busy machine) is followed or missed too, never fewer.
    assert!(s.plan_followed >= 14, "{s:?}");
    assert!(s.missed_commands >= 16, "{s:?}");
    // The frame after each silent step shows the command applied in it.
    let applied = |step: u64| {
        d.observations
            .iter()
            .find(|o| o.step == step + 1)
            .map(|o| o.command)
    };
    for step in 40..54 {
        assert_eq!(
            applied(step),
            Some(plan[((step - 39) / 5) as usize]),
            "step {step}"
        );
    }
    assert_ne!(applied(55), Some(plan[2]), "the plan ran out at step 54");
}
