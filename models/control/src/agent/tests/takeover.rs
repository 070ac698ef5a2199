//! Taking over and giving back: only on the line, only with a first plan in hand, and trust
//! that a swing of the model's error or probe does not end.

use super::*;

#[test]
fn active_inference_takes_over_only_with_a_first_plan_in_hand() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(2, TRUSTED);
    let mut a = agent(&cfg());
    // Real time, and the planner never done in time (a cold planner): the rule keeps driving,
    // trying again each time the planner is free.
    let mut never = FirstOnly {
        answered: true,
        ..Default::default()
    };
    for _ in 0..60 {
        let t = Tick {
            lockstep: false,
            ..tick(&frame, CENTRED, [8.0; 2])
        };
        let d = a.step(&t, &mut model, &mut never).unwrap();
        assert_ne!(d.driver, Driver::ActiveInference);
    }
    assert_eq!(a.stats.switches_to_active_inference, 0);
    assert_eq!(
        a.stats.late_plans, 0,
        "no plan was due: active inference never drove"
    );
}

#[test]
fn takes_over_only_with_the_car_on_the_line() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(1, TRUSTED);
    let mut plans = still_planner();
    let mut a = agent(&cfg());
    for _ in 0..10 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    // Trusted and a preference learnt, but the line is gone (an exploration segment).
    let floor = [0.85f32; 96];
    for _ in 0..40 {
        let d = a
            .step(&tick(&floor, [false; 3], [8.0; 2]), &mut model, &mut plans)
            .unwrap();
        assert_ne!(
            d.driver,
            Driver::ActiveInference,
            "never taking over off the line"
        );
    }
    let mut k = 0;
    while !a.driving_by_active_inference() {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
        k += 1;
        assert!(k < 30, "takes over once the line has been found for 0.5 s");
    }
    assert_eq!(
        k, 26,
        "25 steps, then one (a model step here) to make the first plan"
    );
    assert_eq!(a.stats.fallbacks, 0);
}

#[test]
fn weights_that_fail_their_probe_wait_while_the_model_in_hand_drives() {
    let frame = line_frame(6.0, 0.0);
    let mut model = Toy::new(1, TRUSTED);
    let mut plans = still_planner();
    let mut a = agent(&cfg());
    assert!(
        a.admits(Some(0.2)),
        "the rule drives: any weights may be tried"
    );
    while !a.driving_by_active_inference() {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
        assert!(a.stats.reactive_steps < 100, "no takeover");
    }
    assert!(!a.admits(Some(0.6)), "below min_probe (0.7)");
    assert!(a.admits(Some(0.7)));
    assert!(a.admits(None), "weights never probed are not judged");
}

#[test]
fn distrust_needs_a_sustained_bad_model_and_the_probe_gates_trust() {
    let frame = line_frame(6.0, 0.0);
    let low_probe = Health {
        probe: Some(0.2),
        ..TRUSTED
    };
    let mut model = Toy::new(1, low_probe);
    let mut plans = still_planner();
    let mut a = agent(&cfg());
    for _ in 0..30 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(
        !a.driving_by_active_inference(),
        "a probe below min_probe is not trusted"
    );
    model.health.probe = Some(0.9);
    // One model step arms the takeover (its first plan), the next drives by it.
    for _ in 0..2 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(a.driving_by_active_inference());
    // The probe of the model in hand is what the trust was earned with: it is not judged again
    // (newer weights that fail it wait instead, see `weights_that_fail_...`).
    model.health.probe = Some(0.5);
    for _ in 0..5 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(a.driving_by_active_inference());
    // A ratio above distrust_ratio for fewer than distrust_after_steps model steps is a swing.
    model.health.model_over_copy = Some(2.0);
    for _ in 0..40 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(a.driving_by_active_inference());
    for _ in 0..20 {
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
    }
    assert!(
        !a.driving_by_active_inference(),
        "sustained: the rule drives again"
    );
    assert_eq!(a.stats.switches_to_reactive, 1);
}

/// NaN compares false with every threshold; a model whose error turned NaN (or inf) must lose
/// the wheel at its next model step, not keep it forever or after a grace period.
#[test]
fn a_model_whose_error_is_not_finite_hands_the_wheel_back_at_once() {
    let frame = line_frame(6.0, 0.0);
    for broken in [f64::NAN, f64::INFINITY] {
        let mut model = Toy::new(1, TRUSTED);
        let mut plans = still_planner();
        let mut a = agent(&cfg());
        for _ in 0..30 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
                .unwrap();
        }
        assert!(a.driving_by_active_inference());
        model.health.model_over_copy = Some(broken);
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
            .unwrap();
        assert!(!a.driving_by_active_inference(), "{broken}: still driving");
        for _ in 0..100 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
                .unwrap();
        }
        assert!(!a.driving_by_active_inference(), "{broken}: trusted again");
        assert_eq!(a.stats.switches_to_reactive, 1);
    }
}

/// Exploration is for learning a model; weights fit for control (a passing probe, e.g. from a
/// checkpoint) wait for the preference on the line, so active inference takes over sooner.
#[test]
fn weights_fit_for_control_wait_for_the_preference_without_exploring() {
    let frame = line_frame(6.0, 0.0);
    let exploring = |probe: Option<f64>| {
        let cfg = AgentConfig {
            preference_frames: 1000,
            ..cfg()
        };
        let explore = ExplorationConfig {
            segments_per_s: 5.0,
            ..Default::default()
        };
        let mut a = Agent::new(
            &cfg,
            &ReactiveConfig::default(),
            &explore,
            FrameShape::CAR,
            0.02,
        );
        let health = Health {
            probe,
            ..Health::default()
        };
        let mut model = Toy::new(2, health);
        let mut plans = still_planner();
        for _ in 0..200 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans)
                .unwrap();
        }
        a.stats.exploration_steps
    };
    assert!(
        exploring(None) > 0,
        "a model without a probe is still learning"
    );
    assert!(
        exploring(Some(0.5)) > 0,
        "a probe below min_probe: still learning"
    );
    assert_eq!(exploring(Some(0.9)), 0);
}
