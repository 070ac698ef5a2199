//! The teacher drives every shipped track; laps are counted honestly.

use mtanet_scenes::{
    CONTROL_PERIOD_S, SceneConfig, Sensors, Teacher, TeacherConfig, World, shipped_track,
};

struct Run {
    laps: u32,
    max_abs_lateral: f64,
    lateral_sq_sum: f64,
    steps: usize,
    commands: Vec<[f32; 2]>,
}

fn drive(track: &str, teacher: &TeacherConfig, seconds: f64) -> (World, Run) {
    let mut w = World::new(&SceneConfig::default().with_track(shipped_track(track))).unwrap();
    let mut t = Teacher::new(teacher);
    let steps = (seconds / CONTROL_PERIOD_S).round() as usize;
    let mut run = Run {
        laps: 0,
        max_abs_lateral: 0.0,
        lateral_sq_sum: 0.0,
        steps,
        commands: Vec::with_capacity(steps),
    };
    let mut s: Sensors = w.sense();
    for _ in 0..steps {
        let cmd = t.act(&s);
        run.commands.push(cmd);
        assert!(w.step(cmd), "teacher produced a non-finite command {cmd:?}");
        s = w.sense();
        run.max_abs_lateral = run.max_abs_lateral.max(s.truth.lateral_m.abs());
        run.lateral_sq_sum += s.truth.lateral_m * s.truth.lateral_m;
    }
    run.laps = s.truth.laps;
    assert_eq!(w.rejected_commands(), 0);
    (w, run)
}

#[test]
fn teacher_does_two_laps_of_the_oval_in_60_s_without_leaving_the_line() {
    let (w, run) = drive("oval", &TeacherConfig::default(), 60.0);
    let half = w.track().line_width_m() / 2.0;
    assert!(run.laps >= 2, "only {} laps in 60 s", run.laps);
    assert!(
        run.max_abs_lateral < half,
        "left the line: max |lateral| {:.4} m >= {half} m",
        run.max_abs_lateral
    );
    // Laps agree with the distance driven.
    let expected = (w.progress_m() / w.track().length_m()).floor() as u32;
    assert_eq!(run.laps, expected);
    assert!((w.time_s() - 60.0).abs() < 1e-9, "time {}", w.time_s());
}

#[test]
fn teacher_laps_every_shipped_track() {
    for track in ["oval", "bends", "s_loop", "square"] {
        let (w, run) = drive(track, &TeacherConfig::default(), 45.0);
        let width = w.track().line_width_m();
        assert!(
            run.laps >= 1,
            "{track}: no lap in 45 s (progress {:.2} m)",
            w.progress_m()
        );
        // Near the line: the bar centre never farther than one line width from it.
        assert!(
            run.max_abs_lateral < width,
            "{track}: max |lateral| {:.4} m",
            run.max_abs_lateral
        );
    }
}

#[test]
fn teacher_is_deterministic_and_noise_widens_the_data() {
    let clean = TeacherConfig::default();
    let noisy = TeacherConfig {
        noise_std: 2.0,
        seed: 7,
        ..TeacherConfig::default()
    };
    let (_, a) = drive("oval", &noisy, 20.0);
    let (_, b) = drive("oval", &noisy, 20.0);
    assert_eq!(a.commands, b.commands, "same seed, different commands");
    let (_, c) = drive(
        "oval",
        &TeacherConfig {
            seed: 8,
            ..noisy.clone()
        },
        20.0,
    );
    assert_ne!(a.commands, c.commands, "seed has no effect");
    let (_, base) = drive("oval", &clean, 20.0);
    let rms = |r: &Run| (r.lateral_sq_sum / r.steps as f64).sqrt();
    assert!(
        rms(&a) > 1.3 * rms(&base),
        "noise did not widen the lateral spread: {:.4} vs {:.4}",
        rms(&a),
        rms(&base)
    );
    // Still a usable recording: the noisy car keeps following the track.
    let (w, long) = drive("oval", &noisy, 60.0);
    assert!(
        long.laps >= 1,
        "noisy teacher lost the track: {:.2} m",
        w.progress_m()
    );
}

#[test]
fn backing_over_the_start_does_not_count_laps() {
    let mut w = World::new(&SceneConfig::default()).unwrap();
    // Reverse from the start for 3 s: the car crosses the start backwards.
    for _ in 0..150 {
        w.step([-6.0, -6.0]);
    }
    let s = w.sense();
    assert!(w.progress_m() < -0.2, "progress {}", w.progress_m());
    assert_eq!(s.truth.laps, 0);
    assert!(
        s.truth.track_s > w.track().length_m() - 0.5,
        "{:?}",
        s.truth
    );
    // Forward again across the start: still no lap.
    for _ in 0..300 {
        w.step([6.0, 6.0]);
    }
    assert!(w.progress_m() > 0.2);
    assert_eq!(w.sense().truth.laps, 0);
}

#[test]
fn lateral_sign_convention() {
    // Positive lateral = the line is to the car's left.
    let mut w = World::new(&SceneConfig::default()).unwrap();
    w.set_pose(-0.2, -0.01, 0.0); // car right of the line (y = 0), heading +x
    let t = w.sense().truth;
    assert!(t.lateral_m > 0.009 && t.lateral_m < 0.011, "{t:?}");
    assert!(t.on_line);
    w.set_pose(-0.2, 0.02, 0.0);
    let t = w.sense().truth;
    assert!(t.lateral_m < -0.019 && !t.on_line, "{t:?}");
    // Facing the other way, the same place flips the sign.
    w.set_pose(-0.2, 0.02, std::f64::consts::PI);
    assert!(w.sense().truth.lateral_m > 0.019);
    let t = w.sense().truth;
    assert!(
        (t.x + 0.2).abs() < 1e-9 && (t.y - 0.02).abs() < 1e-9,
        "{t:?}"
    );
    assert!((t.yaw.abs() - std::f64::consts::PI).abs() < 1e-9, "{t:?}");
}

#[test]
fn place_on_track_and_start_anywhere() {
    let mut w = World::new(&SceneConfig::default().with_track(shipped_track("s_loop"))).unwrap();
    let len = w.track().length_m();
    for k in 0..20 {
        let s_m = len * k as f64 / 20.0;
        let lat = 0.01 * ((k % 5) as f64 - 2.0);
        w.place_on_track(s_m, lat, 0.0);
        let t = w.sense().truth;
        let ds = (t.track_s - s_m + len / 2.0).rem_euclid(len) - len / 2.0;
        assert!(ds.abs() < 0.01, "s {s_m}: truth {t:?}");
        assert!(
            (t.lateral_m - lat).abs() < 2e-3,
            "lateral {lat}: truth {t:?}"
        );
    }
    // A world configured to start half way round starts there, on the line, and laps from there.
    let cfg = SceneConfig {
        start_s_m: len / 2.0,
        ..SceneConfig::default().with_track(shipped_track("s_loop"))
    };
    let mut w = World::new(&cfg).unwrap();
    let s = w.sense();
    assert!((s.truth.track_s - len / 2.0).abs() < 1e-6, "{:?}", s.truth);
    assert_eq!(s.line, [false, true, false]);
    let mut t = Teacher::new(&TeacherConfig::default());
    let mut s = s;
    for _ in 0..2000 {
        let c = t.act(&s);
        w.step(c);
        s = w.sense();
    }
    assert!(s.truth.laps >= 1, "progress {}", w.progress_m());
    w.reset();
    assert!((w.sense().truth.track_s - len / 2.0).abs() < 1e-6);
}

#[test]
fn middle_line_sensor_agrees_with_ground_truth() {
    // Two independent paths to "over the line": a MuJoCo ray against the line geoms, and the
    // distance to the track polyline. They must agree except within 1 mm of the line's edge.
    for track in ["oval", "bends", "s_loop", "square"] {
        let noisy = TeacherConfig {
            noise_std: 3.0,
            seed: 3,
            ..TeacherConfig::default()
        };
        let mut w = World::new(&SceneConfig::default().with_track(shipped_track(track))).unwrap();
        let half = w.track().line_width_m() / 2.0;
        let mut t = Teacher::new(&noisy);
        let mut s = w.sense();
        let (mut on, mut off) = (0, 0);
        for k in 0..1500 {
            let c = t.act(&s);
            w.step(c);
            s = w.sense();
            let lat = s.truth.lateral_m.abs();
            if (lat - half).abs() < 1e-3 {
                continue;
            }
            assert_eq!(
                s.line[1],
                lat < half,
                "{track} step {k}: {:?} {:?}",
                s.line,
                s.truth
            );
            if s.line[1] { on += 1 } else { off += 1 }
        }
        assert!(
            on > 100 && off > 10,
            "{track}: on {on}, off {off}: not both cases exercised"
        );
    }
}

/// The loop core every driver steps through: a car reversing along the line is put back as a
/// new episode within the reset window, and laps keep counting over episodes.
#[test]
fn the_drive_puts_a_car_going_the_wrong_way_back_and_counts_laps_over_episodes() {
    use mtanet_scenes::{Circuit, ResetRule, Verdict};
    use mtanet_summaries::CommandSource;
    let teacher = CommandSource::Teacher;
    let mut w = World::new(&SceneConfig::default().with_track(shipped_track("oval"))).unwrap();
    let mut t = Teacher::new(&TeacherConfig::default());
    let rule = ResetRule::default();
    let mut car = Circuit::new(&mut w, rule);
    let mut laps = 0;
    // The teacher laps once...
    while laps < 1 {
        let f = car.sense();
        let stepped = car.step(t.act(&f.sensors), teacher);
        assert!(stepped.accepted && stepped.reset.is_none(), "{stepped:?}");
        laps = stepped.laps;
        assert!(car.steps() < 3000, "no lap in 60 s");
    }
    // ...then the car backs up along the line until it is put back at the start.
    let window = (rule.after_lost_s / CONTROL_PERIOD_S) as u64;
    let backing = car.steps();
    let reset = loop {
        let stepped = car.step([-8.0, -8.0], teacher);
        assert_eq!(stepped.laps, laps, "reversing completes no lap");
        if let Some(v) = stepped.reset {
            break v;
        }
        assert!(car.steps() - backing < 3 * window, "never put back");
    };
    assert_eq!(reset, Verdict::WrongWay);
    assert_eq!(car.episode(), 1);
    let f = car.sense();
    assert_eq!((f.episode, f.step), (1, car.steps()));
    assert!(
        f.time_s < 1e-9,
        "a new episode starts at time 0: {}",
        f.time_s
    );
    // The lap of the first episode still counts after the reset.
    t.reset();
    let stepped = car.step(t.act(&f.sensors), teacher);
    assert_eq!(stepped.laps, laps);
    // The score saw every step, the lap included, all of them the teacher's.
    let score = car.score();
    assert_eq!(score.steps(), car.steps());
    assert_eq!(score.laps(), laps);
    assert_eq!(score.steps_of(teacher), car.steps());
    assert_eq!(score.laps_under_active_inference(), 0);
}

/// A drive round several tracks: after the set time on one the car is at the start of the next
/// (a new episode, time 0, the next track under its bar), then back on the first; laps and the
/// score run on over the switches.
#[test]
fn a_drive_round_several_tracks_moves_to_the_next_after_the_set_time() {
    use mtanet_scenes::{Circuit, ResetRule};
    use mtanet_summaries::CommandSource;
    let scene = |t: &str| SceneConfig::default().with_track(shipped_track(t));
    let mut worlds = vec![
        World::new(&scene("oval")).unwrap(),
        World::new(&scene("square")).unwrap(),
    ];
    let lengths: Vec<f64> = worlds.iter().map(|w| w.track().length_m()).collect();
    assert!((lengths[0] - lengths[1]).abs() > 0.01, "{lengths:?}");
    let mut t = Teacher::new(&TeacherConfig::default());
    let mut car = Circuit::round(&mut worlds, ResetRule::default(), 1.0);
    let per_track = (1.0 / CONTROL_PERIOD_S).round() as u64;
    let mut switches = Vec::new();
    while switches.len() < 2 {
        let f = car.sense();
        let stepped = car.step(t.act(&f.sensors), CommandSource::Teacher);
        assert!(
            stepped.reset.is_none(),
            "the teacher is not lost: {stepped:?}"
        );
        if let Some(next) = stepped.switched_to {
            t.reset();
            switches.push((car.steps(), next, car.episode()));
            let f = car.sense();
            assert!(
                f.time_s < 1e-9,
                "a new track starts at time 0: {}",
                f.time_s
            );
            assert_eq!(car.world().track().length_m(), lengths[next]);
            assert!(
                f.sensors.truth.lateral_m.abs() < 0.005,
                "at the next start, on its line"
            );
        }
        assert!(car.steps() < 10 * per_track, "no switch in 10 s");
    }
    assert_eq!(
        switches,
        vec![(per_track, 1, 1), (2 * per_track, 0, 2)],
        "(step, track, episode) of each switch"
    );
    assert_eq!(car.track_index(), 0);
    assert_eq!(car.score().steps(), car.steps());
}
