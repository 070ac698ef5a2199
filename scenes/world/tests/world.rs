//! World contract: determinism, rejected commands, reset, configuration errors.

use mtanet_scenes::{
    IMAGE_PIXELS, SceneConfig, SceneError, Sensors, Teacher, TeacherConfig, World,
};

fn bits(img: &[f32; IMAGE_PIXELS]) -> [u32; IMAGE_PIXELS] {
    img.map(f32::to_bits)
}

#[test]
fn same_seed_and_commands_give_bit_identical_images() {
    let cfg = SceneConfig {
        side_cameras: true,
        ..SceneConfig::default().with_track(mtanet_scenes::shipped_track("s_loop"))
    };
    let noisy = TeacherConfig {
        noise_std: 2.0,
        seed: 42,
        ..TeacherConfig::default()
    };
    let mut worlds = [World::new(&cfg).unwrap(), World::new(&cfg).unwrap()];
    let mut teachers = [Teacher::new(&noisy), Teacher::new(&noisy)];
    let mut sensors: Vec<Sensors> = worlds.iter_mut().map(|w| w.sense()).collect();
    let mut changed = 0;
    for k in 0..1500 {
        for i in 0..2 {
            let cmd = teachers[i].act(&sensors[i]);
            worlds[i].step(cmd);
            let prev = bits(&sensors[i].image);
            sensors[i] = worlds[i].sense();
            if i == 0 && prev != bits(&sensors[i].image) {
                changed += 1;
            }
        }
        let (a, b) = (&sensors[0], &sensors[1]);
        assert_eq!(bits(&a.image), bits(&b.image), "image differs at step {k}");
        let (sa, sb) = (a.side_images.unwrap(), b.side_images.unwrap());
        assert_eq!(bits(&sa[0]), bits(&sb[0]), "left image differs at step {k}");
        assert_eq!(
            bits(&sa[1]),
            bits(&sb[1]),
            "right image differs at step {k}"
        );
        assert_eq!(a.line, b.line);
        assert_eq!(
            a.wheel_velocity.map(f32::to_bits),
            b.wheel_velocity.map(f32::to_bits)
        );
        assert_eq!(a.truth, b.truth, "truth differs at step {k}");
    }
    // The comparison was about moving images, not a parked car.
    assert!(
        changed > 300,
        "image changed on only {changed} of 1500 steps"
    );
}

#[test]
fn reset_restores_the_start_exactly() {
    let mut w = World::new(&SceneConfig::default()).unwrap();
    let start = w.sense();
    let mut t = Teacher::new(&TeacherConfig::default());
    let mut s = start;
    for _ in 0..200 {
        let c = t.act(&s);
        w.step(c);
        s = w.sense();
    }
    assert!(w.time_s() > 3.9);
    assert_ne!(bits(&s.image), bits(&start.image));
    w.reset();
    assert_eq!(w.time_s(), 0.0);
    assert_eq!(w.command(), [0.0, 0.0]);
    let again = w.sense();
    assert_eq!(bits(&again.image), bits(&start.image));
    assert_eq!(again.truth, start.truth);
    // A fresh run after reset repeats the first run exactly.
    let mut t = Teacher::new(&TeacherConfig::default());
    let mut s2 = again;
    let mut w2 = World::new(&SceneConfig::default()).unwrap();
    let mut s3 = w2.sense();
    let mut t3 = Teacher::new(&TeacherConfig::default());
    for _ in 0..200 {
        let c = t.act(&s2);
        w.step(c);
        s2 = w.sense();
        let c3 = t3.act(&s3);
        w2.step(c3);
        s3 = w2.sense();
        assert_eq!(bits(&s2.image), bits(&s3.image));
    }
}

#[test]
fn non_finite_commands_are_rejected_counted_and_the_last_good_one_kept() {
    let mut w = World::new(&SceneConfig::default()).unwrap();
    assert!(w.step([5.0, 5.0]));
    for bad in [
        [f32::NAN, 1.0],
        [1.0, f32::INFINITY],
        [f32::NEG_INFINITY, f32::NAN],
    ] {
        assert!(!w.step(bad), "{bad:?} accepted");
        assert_eq!(
            w.command(),
            [5.0, 5.0],
            "last good command not kept after {bad:?}"
        );
    }
    assert_eq!(w.rejected_commands(), 3);
    // The car kept driving on the good command.
    for _ in 0..20 {
        assert!(!w.step([f32::NAN, f32::NAN]));
    }
    let s = w.sense();
    assert!(
        s.wheel_velocity.iter().all(|v| (v - 5.0).abs() < 0.3),
        "{:?}",
        s.wheel_velocity
    );
    assert!(s.truth.x.is_finite() && s.image.iter().all(|p| p.is_finite()));
    assert_eq!(w.rejected_commands(), 23);
    // Out-of-range commands are clamped, not rejected.
    assert!(w.step([1e9, -1e9]));
    let lim = w.config().max_wheel_speed;
    assert_eq!(w.command(), [lim, -lim]);
    assert_eq!(w.rejected_commands(), 23);
}

#[test]
fn wheel_velocity_sensors_follow_the_command() {
    let mut w = World::new(&SceneConfig::default()).unwrap();
    for _ in 0..25 {
        w.step([4.0, -3.0]);
    }
    let v = w.sense().wheel_velocity;
    assert!(
        (v[0] - 4.0).abs() < 0.3 && (v[1] + 3.0).abs() < 0.3,
        "{v:?}"
    );
    // Spinning left wheel forward, right backward turns the car clockwise (yaw decreases).
    assert!(w.sense().truth.yaw < -0.3, "{:?}", w.sense().truth);
}

#[test]
fn bad_config_names_the_field() {
    let check = |cfg: SceneConfig, field: &str| {
        let err = match World::new(&cfg) {
            Ok(_) => panic!("accepted bad {field}"),
            Err(e) => e,
        };
        assert!(matches!(err, SceneError::Config { .. }), "{err}");
        assert!(err.to_string().contains(field), "{err}");
    };
    let d = SceneConfig::default;
    check(
        SceneConfig {
            physics_timestep_s: 0.0,
            ..d()
        },
        "physics_timestep_s",
    );
    check(
        SceneConfig {
            physics_timestep_s: f64::NAN,
            ..d()
        },
        "physics_timestep_s",
    );
    check(
        SceneConfig {
            control_period_s: 0.013,
            ..d()
        },
        "control_period_s",
    );
    check(
        SceneConfig {
            max_wheel_speed: -1.0,
            ..d()
        },
        "max_wheel_speed",
    );
    // Other periods that are whole multiples work: 10 physics steps of 2 ms.
    let w = World::new(&SceneConfig {
        physics_timestep_s: 0.002,
        ..d()
    })
    .unwrap();
    assert_eq!(w.substeps(), 10);
}

#[test]
fn config_files_are_strict() {
    let cfg: SceneConfig = toml::from_str("side_cameras = true").unwrap();
    assert!(cfg.side_cameras);
    assert!(cfg.track.ends_with("tracks/oval.csv"), "{:?}", cfg.track);
    let err = toml::from_str::<SceneConfig>("side_camera = true").unwrap_err();
    assert!(err.to_string().contains("side_camera"), "{err}");
    let err = toml::from_str::<TeacherConfig>("cruise = 5.0\nnoise = 1.0").unwrap_err();
    assert!(err.to_string().contains("noise"), "{err}");
}

#[test]
fn world_can_move_to_another_thread() {
    // The simulator may build the world on one thread and run it on another.
    fn assert_send<T: Send>() {}
    assert_send::<World>();
    assert_send::<Teacher>();
    assert_send::<Sensors>();
}

#[test]
fn non_finite_poses_are_ignored() {
    let mut w = World::new(&SceneConfig::default()).unwrap();
    let before = w.sense().truth;
    assert!(!w.set_pose(f64::NAN, 0.0, 0.0));
    assert!(!w.set_pose(0.0, 0.0, f64::INFINITY));
    assert!(!w.place_on_track(f64::NAN, 0.0, 0.0));
    assert_eq!(w.sense().truth, before);
    assert!(w.set_pose(0.1, 0.2, 0.3));
    let t = w.sense().truth;
    assert!((t.x - 0.1).abs() < 1e-9 && (t.y - 0.2).abs() < 1e-9 && (t.yaw - 0.3).abs() < 1e-9);
}

#[test]
fn bare_steps_then_control_steps_stay_consistent() {
    // Bare mj_steps (benchmarks) leave kinematics one step behind; the next sense must not.
    let mut a = World::new(&SceneConfig::default()).unwrap();
    let mut b = World::new(&SceneConfig::default()).unwrap();
    a.step([6.0, 6.0]);
    b.step([6.0, 6.0]);
    for _ in 0..a.substeps() {
        a.mj_step_bare();
    }
    b.step([6.0, 6.0]);
    let (sa, sb) = (a.sense(), b.sense());
    assert!(
        (sa.truth.x - sb.truth.x).abs() < 1e-6,
        "{:?} vs {:?}",
        sa.truth,
        sb.truth
    );
    assert_eq!(bits(&sa.image), bits(&sb.image));
}

#[test]
fn a_restored_snapshot_replays_the_same_future_bit_for_bit() {
    let cfg = SceneConfig::default().with_track(mtanet_scenes::shipped_track("bends"));
    let mut w = World::new(&cfg).unwrap();
    let mut t = Teacher::new(&TeacherConfig {
        noise_std: 2.0,
        seed: 3,
        ..TeacherConfig::default()
    });
    let mut s = w.sense();
    for _ in 0..150 {
        w.step(t.act(&s));
        s = w.sense();
    }
    let snap = w.snapshot();
    let future = |w: &mut World, turn: f32| -> Vec<Sensors> {
        (0..40)
            .map(|_| {
                w.step([6.0 - turn, 6.0 + turn]);
                w.sense()
            })
            .collect()
    };
    let first = future(&mut w, 3.0);
    // Another future in between, then back: the snapshot holds everything the future needs.
    w.restore(&snap);
    let other = future(&mut w, -3.0);
    w.restore(&snap);
    let again = future(&mut w, 3.0);
    for (k, (a, b)) in first.iter().zip(&again).enumerate() {
        assert_eq!(bits(&a.image), bits(&b.image), "image differs at step {k}");
        assert_eq!(a.truth, b.truth, "truth differs at step {k}");
        assert_eq!(
            a.wheel_velocity.map(f32::to_bits),
            b.wheel_velocity.map(f32::to_bits)
        );
    }
    assert_ne!(
        first.last().unwrap().truth,
        other.last().unwrap().truth,
        "the two futures must differ, or the test shows nothing"
    );
}
