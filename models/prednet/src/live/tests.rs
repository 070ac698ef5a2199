use super::*;
use crate::{TrainConfig, Trainer};

fn checkpoint(seed: u64) -> Vec<u8> {
    let cfg = ModelConfig {
        channels: vec![4, 4, 4],
        a_channels: vec![1, 4, 4],
        ..Default::default()
    };
    Trainer::new(
        &cfg,
        &TrainConfig {
            seed,
            ..Default::default()
        },
    )
    .checkpoint_bytes(None)
    .unwrap()
}

fn frame(v: f32) -> Vec<f32> {
    (0..96).map(|i| v + 0.002 * i as f32).collect()
}

#[test]
fn steps_judges_and_takes_new_weights_in_place() {
    let mut m = LiveModel::from_bytes(&checkpoint(1), 1).unwrap();
    assert_eq!(m.error_ratio(), None, "no statistics yet");
    for i in 0..5 {
        assert!(
            m.observe_frame(&frame(0.2 + 0.1 * i as f32), [8.0, 8.0])
                .unwrap()
                .is_finite()
        );
    }
    assert!(m.error_ratio().is_some());
    // A still view is not scored (copying the last frame is trivially right there).
    let before = (m.model_mse.get(), m.copy_mse.get());
    m.observe_frame(&frame(0.6), [8.0, 8.0]).unwrap();
    assert_eq!((m.model_mse.get(), m.copy_mse.get()), before);
    let mut fresh = LiveModel::from_bytes(&checkpoint(2), 2).unwrap();
    assert!(m.take_weights(&mut fresh));
    assert_eq!(
        (m.version, m.steps),
        (2, 6),
        "same network: weights swapped, state kept"
    );
    let mut bad = checkpoint(3);
    bad.truncate(bad.len() / 2);
    assert!(
        LiveModel::from_bytes(&bad, 3).is_err(),
        "a damaged checkpoint never becomes a model"
    );
}

#[test]
fn taken_weights_predict_as_the_model_they_came_from() {
    let run = |m: &mut LiveModel| {
        (0..4)
            .map(|i| {
                m.observe_frame(&frame(0.2 + 0.1 * i as f32), [7.0, 9.0])
                    .unwrap()
            })
            .collect::<Vec<f64>>()
    };
    // One set of bytes for both: the tests share libtorch's global generator, so two
    // calls of `checkpoint(2)` running beside other tests need not draw the same weights.
    let (one, two) = (checkpoint(1), checkpoint(2));
    let want = run(&mut LiveModel::from_bytes(&two, 2).unwrap());
    let mut m = LiveModel::from_bytes(&one, 1).unwrap();
    let mut fresh = LiveModel::from_bytes(&two, 2).unwrap();
    assert!(m.take_weights(&mut fresh));
    assert_eq!(m.version, 2);
    assert_eq!(
        run(&mut m),
        want,
        "the packed step weights came along with the values"
    );
    let mut other = LiveModel::from_bytes(
        &Trainer::new(&ModelConfig::default(), &TrainConfig::default())
            .checkpoint_bytes(None)
            .unwrap(),
        3,
    )
    .unwrap();
    assert!(!m.take_weights(&mut other), "another network is refused");
    assert_eq!(m.version, 2);
}

#[test]
fn a_reset_forgets_the_past_episode() {
    let ck = checkpoint(1);
    let first = LiveModel::from_bytes(&ck, 1)
        .unwrap()
        .observe_frame(&frame(0.7), [8.0; 2])
        .unwrap();
    let mut m = LiveModel::from_bytes(&ck, 1).unwrap();
    for i in 0..5 {
        m.observe_frame(&frame(0.1 * i as f32), [8.0; 2]).unwrap();
    }
    let kept = m.observe_frame(&frame(0.7), [8.0; 2]).unwrap();
    assert_ne!(
        kept, first,
        "the past shapes the prediction without a reset"
    );
    m.reset_state();
    assert_eq!(
        m.observe_frame(&frame(0.7), [8.0; 2]).unwrap(),
        first,
        "as if it never ran"
    );
}

#[test]
fn imagination_rolls_each_plan_out_in_one_batch_like_single_steps() {
    let ck = checkpoint(4);
    let mut live = LiveModel::from_bytes(&ck, 1).unwrap();
    for i in 0..4 {
        live.observe_frame(&frame(0.3 + 0.05 * i as f32), [7.0, 9.0])
            .unwrap();
    }
    let plans = vec![
        vec![Drive::new(8.0, 0.0), Drive::new(8.0, 2.0)],
        vec![Drive::new(4.0, -3.0), Drive::new(10.0, 1.0)],
    ];
    let mut im = Imagined::from_bytes(&ck).unwrap();
    im.start(live.state().deep_copy(), [8.0, 8.0]).unwrap();
    let batched = im.imagine(&plans).unwrap();
    assert_eq!((batched.len(), batched[0].len()), (2, 2 * 96));
    assert_ne!(
        batched[0], batched[1],
        "different commands, different futures"
    );
    // The second plan alone, step by step, gives the same frames.
    let _g = tch::no_grad_guard();
    let net = im.model();
    let a = |w: [f32; 2]| Tensor::from_slice(&w).view([1, 2]);
    let (mut s, _) = net.f_imagine_step(live.state(), &a([8.0, 8.0])).unwrap();
    let mut alone = Vec::new();
    for d in &plans[1] {
        let (next, pred) = net.f_imagine_step(&s, &a(d.wheels())).unwrap();
        alone.extend(Vec::<f32>::try_from(pred.flatten(0, -1)).unwrap());
        s = next;
    }
    for (x, y) in alone.iter().zip(&batched[1]) {
        assert!((x - y).abs() < 1e-5, "{x} vs {y}");
    }
    // With a deadline: the same frames when there is time, nothing once it has passed.
    let later = Instant::now() + std::time::Duration::from_secs(60);
    assert_eq!(im.imagine_until(&plans, later).unwrap(), Some(batched));
    assert_eq!(im.imagine_until(&plans, Instant::now()).unwrap(), None);
}

#[test]
fn a_non_finite_error_makes_the_average_infinite_until_a_finite_one_restarts_it() {
    let mut e = Ema::default();
    e.push(0.5);
    e.push(f64::NAN);
    assert_eq!(e.get(), Some(f64::INFINITY));
    e.push(0.25);
    assert_eq!(e.get(), Some(0.25));
    e.push(0.75);
    assert!((e.get().unwrap() - 0.26).abs() < 1e-12);
}
