//! The fast form of the network (fused unit convolution, one MLP call per sequence, shared
//! candidate work, imagined steps skipping a zero E_0) against the straightforward form in
//! `reference.rs`, on random weights and inputs: outputs, states and gradients agree to 1e-5.

use mtanet_models::{ModelConfig, MtaPredNet, State, StepWeights, reference};
use tch::{Device, Kind, Tensor, nn};

const TOL: f64 = 1e-5;

/// Each test draws its weights and inputs from libtorch's one global generator, seeded, on one
/// thread, and alone: the tests of this file run in parallel, and unseeded draws made the float
/// error vary from run to run (a gradient once came out 1.2e-5 apart on a fresh machine).
fn seeded(seed: i64) -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    tch::set_num_threads(1);
    tch::manual_seed(seed);
    g
}

fn configs() -> Vec<(&'static str, ModelConfig)> {
    vec![
        ("default", ModelConfig::default()),
        (
            "1/16/32, 3 units, tau 1.5 at the bottom",
            ModelConfig {
                channels: vec![1, 16, 32],
                a_channels: vec![1, 16, 32],
                gus: vec![3, 2, 1],
                tau: vec![1.5, 1.3, 2.0],
                ..Default::default()
            },
        ),
    ]
}

fn close(what: &str, a: &Tensor, b: &Tensor) {
    assert_eq!(a.size(), b.size(), "{what}: shapes");
    let scale = b.abs().max().double_value(&[]).max(1.0);
    let diff = (a - b).abs().max().double_value(&[]);
    assert!(
        diff <= TOL * scale,
        "{what}: max |fast - reference| = {diff:e} (scale {scale})"
    );
}

fn same_state(what: &str, a: &State, b: &State) {
    assert_eq!(a.imagined, b.imagined, "{what}: imagined flag");
    for (l, (x, y)) in a.layers.iter().zip(&b.layers).enumerate() {
        close(&format!("{what} layer {l} h"), &x.h, &y.h);
        close(&format!("{what} layer {l} c"), &x.c, &y.c);
        close(&format!("{what} layer {l} r"), &x.r, &y.r);
        close(&format!("{what} layer {l} e"), &x.e, &y.e);
    }
}

fn frames(cfg: &ModelConfig, b: i64, t: i64) -> Tensor {
    Tensor::rand(
        [b, t, 1, cfg.image_height, cfg.image_width],
        (Kind::Float, Device::Cpu),
    )
}

fn actions(b: i64, t: i64) -> Tensor {
    Tensor::randn([b, t, 2], (Kind::Float, Device::Cpu)) * 5.0
}

/// A state some observed steps in, so no part of it is zero.
fn warm(model: &MtaPredNet, cfg: &ModelConfig, b: i64) -> State {
    let out = model
        .f_forward_sequence_from(&model.zero_state(b), &frames(cfg, b, 3), &actions(b, 3))
        .unwrap();
    out.state
}

/// Both kinds of step weights, each with the batch sizes to try: libtorch's convolutions, and
/// the packed ones of inference (used up to `packed_conv::MAX_BATCH`).
fn both_weights(model: &MtaPredNet, batches: [i64; 2]) -> Vec<(String, StepWeights, i64)> {
    let mut all = Vec::new();
    for b in batches {
        all.push((format!("weights, batch {b}"), model.weights(), b));
        all.push((
            format!("inference weights, batch {b}"),
            model.inference_weights(),
            b,
        ));
    }
    all
}

#[test]
fn steps_and_imagined_steps_match_the_straightforward_form() {
    let _seed = seeded(1);
    let _g = tch::no_grad_guard();
    for (name, cfg) in configs() {
        let vs = nn::VarStore::new(Device::Cpu);
        let model = MtaPredNet::new(&vs.root(), &cfg);
        for (wname, w, b) in both_weights(&model, [1, 6]) {
            let name = format!("{name}, {wname}");
            let state = warm(&model, &cfg, b);
            let (f, a) = (frames(&cfg, b, 1).select(1, 0), actions(b, 1).select(1, 0));
            let (fast, out) = model.f_step_with(&w, &state, &f, &a).unwrap();
            let (slow, pred) = reference::step(&model, &state, Some(&f), &a);
            close(
                &format!("{name}: observed prediction"),
                &out.prediction,
                &pred,
            );
            same_state(&format!("{name}: observed step"), &fast, &slow);
            // Two imagined steps: the second starts from an imagined state (E_0 = 0 skipped).
            let (mut fast, mut slow) = (fast, slow);
            for i in 0..2 {
                let a = actions(b, 1).select(1, 0);
                let (f_next, f_pred) = model.f_imagine_step_with(&w, &fast, &a).unwrap();
                let (s_next, s_pred) = reference::step(&model, &slow, None, &a);
                close(
                    &format!("{name}: imagined prediction {i}"),
                    &f_pred,
                    &s_pred,
                );
                same_state(&format!("{name}: imagined step {i}"), &f_next, &s_next);
                (fast, slow) = (f_next, s_next);
            }
        }
    }
}

#[test]
fn rollouts_and_candidates_match_one_candidate_at_a_time() {
    let _seed = seeded(2);
    let _g = tch::no_grad_guard();
    for (name, cfg) in configs() {
        let vs = nn::VarStore::new(Device::Cpu);
        let model = MtaPredNet::new(&vs.root(), &cfg);
        let observed = warm(&model, &cfg, 1);
        let (imagined, _) = model
            .f_imagine_step(&observed, &actions(1, 1).select(1, 0))
            .unwrap();
        // K = 2: every convolution packed; K = 5: the shared columns packed, the rest not.
        for (wname, w, k) in both_weights(&model, [2, 5]) {
            let h = 4;
            for (from, start) in [("observed", &observed), ("imagined", &imagined)] {
                let name = format!("{name}, {wname}: from {from}");
                let plans = actions(k, h);
                let (preds, end) = model.f_rollout(&w, start, &plans).unwrap();
                assert_eq!(preds.size(), [k, h, 1, cfg.image_height, cfg.image_width]);
                let mut slow = start.expand(k);
                let mut slow_preds = Vec::new();
                for s in 0..h {
                    let (next, p) = reference::step(&model, &slow, None, &plans.select(1, s));
                    slow_preds.push(p);
                    slow = next;
                }
                close(
                    &format!("{name}: rollout"),
                    &preds,
                    &Tensor::stack(&slow_preds, 1),
                );
                same_state(&format!("{name}: rollout end"), &end, &slow);
            }
        }
        for (from, start) in [("observed", &observed), ("imagined", &imagined)] {
            let one = actions(5, 1).select(1, 0);
            let cand = model.f_predict_candidates(start, &one).unwrap();
            let (_, p) = reference::step(&model, &start.expand(5), None, &one);
            close(&format!("{name}: candidates from {from}"), &cand, &p);
        }
    }
}

#[test]
fn inference_weights_leave_inputs_that_track_gradients_to_libtorch() {
    let _seed = seeded(4);
    let (_, cfg) = configs().remove(0);
    let vs = nn::VarStore::new(Device::Cpu);
    let model = MtaPredNet::new(&vs.root(), &cfg);
    let state = tch::no_grad(|| warm(&model, &cfg, 1));
    let a = actions(1, 1).select(1, 0);
    let frame = frames(&cfg, 1, 1).select(1, 0);
    let grad_of_frame = |w: &StepWeights| {
        let f = frame.copy().set_requires_grad(true);
        let (next, _) = model.f_step_with(w, &state, &f, &a).unwrap();
        // The frame reaches the next prediction only through the convolutions.
        let (_, p) = model.f_imagine_step_with(w, &next, &a).unwrap();
        p.sum(Kind::Float).backward();
        f.grad()
    };
    let plain = grad_of_frame(&model.weights());
    let packed = grad_of_frame(&model.inference_weights());
    assert!(
        plain.abs().sum(Kind::Float).double_value(&[]) > 0.0,
        "the frame must matter"
    );
    close("frame gradient through inference weights", &packed, &plain);
}

#[test]
fn training_gradients_match_the_straightforward_form() {
    let _seed = seeded(3);
    for (name, cfg) in configs() {
        let vs = nn::VarStore::new(Device::Cpu);
        let model = MtaPredNet::new(&vs.root(), &cfg);
        let start = tch::no_grad(|| warm(&model, &cfg, 4));
        let (f, a) = (frames(&cfg, 4, 7), actions(4, 7));
        let grads = |use_fast: bool| -> Vec<(String, Tensor)> {
            for v in vs.trainable_variables() {
                let mut g = v.grad();
                if g.defined() {
                    let _ = g.zero_();
                }
            }
            let loss = if use_fast {
                let out = model
                    .f_forward_sequence_imagining(&start, &f, &a, 4)
                    .unwrap();
                // L2 of E_0 is the frame MSE; every step counts.
                out.layer_errors.select(2, 0).sum(Kind::Float)
            } else {
                reference::sequence(&model, &start, &f, &a, 4)
                    .1
                    .sum(Kind::Float)
            };
            loss.backward();
            let mut named: Vec<(String, Tensor)> = vs
                .variables()
                .into_iter()
                .map(|(n, v)| (n, v.grad().copy()))
                .collect();
            named.sort_by(|x, y| x.0.cmp(&y.0));
            named
        };
        let (fast, slow) = (grads(true), grads(false));
        assert!(
            slow.iter()
                .any(|(_, g)| g.abs().sum(Kind::Float).double_value(&[]) > 0.0),
            "{name}: the reference has gradients"
        );
        for ((n, g), (_, r)) in fast.iter().zip(&slow) {
            close(&format!("{name}: gradient of {n}"), g, r);
        }
    }
}
