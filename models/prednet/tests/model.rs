//! Shape contracts and the two reference defects, on small random networks.

use mtanet_models::layer::PredLayer;
use mtanet_models::{ModelConfig, ModelError, MtaPredNet, State};
use tch::{Device, Kind, Tensor, nn};

const F: (Kind, Device) = (Kind::Float, Device::Cpu);

fn small(tau: [f64; 3]) -> ModelConfig {
    ModelConfig::small(&tau)
}

fn build(cfg: &ModelConfig, seed: i64) -> (nn::VarStore, MtaPredNet) {
    tch::set_num_threads(1);
    tch::manual_seed(seed);
    let vs = nn::VarStore::new(Device::Cpu);
    let m = MtaPredNet::new(&vs.root(), cfg);
    (vs, m)
}

/// Runs `steps` random steps from zero and returns the state.
fn warm(m: &MtaPredNet, b: i64, steps: usize) -> State {
    let mut s = m.zero_state(b);
    for _ in 0..steps {
        let (next, _) = m.step(
            &s,
            &Tensor::rand([b, 1, 8, 12], F),
            &(Tensor::rand([b, 2], F) * 2 - 1),
        );
        s = next;
    }
    s
}

#[test]
fn shapes_follow_the_config() {
    let cfg = small([1.0, 1.3, 2.0]);
    let (vs, m) = build(&cfg, 1);
    let _g = tch::no_grad_guard();
    let s = warm(&m, 3, 2);
    let (next, out) = m.step(&s, &Tensor::rand([3, 8, 12], F), &Tensor::rand([3, 2], F));
    assert_eq!(out.prediction.size(), [3, 1, 8, 12]);
    let sizes: Vec<Vec<i64>> = out.errors.iter().map(|e| e.size()).collect();
    assert_eq!(
        sizes,
        [vec![3, 2, 8, 12], vec![3, 8, 4, 6], vec![3, 12, 2, 3]]
    );
    assert_eq!(next.layers[2].h.select(1, 1 as i64).size(), [3, 8, 2, 3]);
    let seq = m.forward_sequence(&Tensor::rand([2, 5, 8, 12], F), &Tensor::rand([2, 5, 2], F));
    assert_eq!(seq.predictions.size(), [2, 5, 1, 8, 12]);
    assert_eq!(seq.layer_errors.size(), [2, 5, 3]);
    // Every variable sits at a stable, named path (checkpoints depend on it).
    let names = vs.variables();
    for n in [
        "layer0.units.wx",
        "layer0.units.wh",
        "layer0.units.bias",
        "layer2.action_mlp.fc2.weight",
        "layer1.input.weight",
        "layer2.xhat.bias",
    ] {
        assert!(names.contains_key(n), "missing {n}: {:?}", names.keys());
    }
    assert!(
        !names.contains_key("layer0.input.weight"),
        "layer 0's X is the image"
    );
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let (_vs, m) = build(&small([1.0, 1.3, 2.0]), 2);
    let s = m.zero_state(2);
    let e = m
        .f_step(
            &s,
            &Tensor::rand([2, 1, 8, 10], F),
            &Tensor::rand([2, 2], F),
        )
        .unwrap_err();
    assert!(matches!(e, ModelError::FrameShape { .. }), "{e}");
    let e = m
        .f_step(
            &s,
            &Tensor::rand([2, 1, 8, 12], F),
            &Tensor::rand([2, 3], F),
        )
        .unwrap_err();
    assert!(matches!(e, ModelError::ActionShape { .. }), "{e}");
    let e = m
        .f_step(
            &s,
            &Tensor::rand([3, 1, 8, 12], F),
            &Tensor::rand([3, 2], F),
        )
        .unwrap_err();
    assert!(
        matches!(e, ModelError::FrameShape { .. }),
        "batch 3 frames for a batch 2 state: {e}"
    );
    let frame64 = Tensor::rand([2, 1, 8, 12], (Kind::Double, Device::Cpu));
    assert!(matches!(
        m.f_step(&s, &frame64, &Tensor::rand([2, 2], F)),
        Err(ModelError::Kind { .. })
    ));
    let e = m
        .f_predict_candidates(&s, &Tensor::rand([5, 2], F))
        .unwrap_err();
    assert!(matches!(e, ModelError::Batch { state: 2, input: 5 }), "{e}");
}

#[test]
fn candidates_match_single_steps_and_depend_on_the_action() {
    let (_vs, m) = build(&small([1.0, 1.3, 2.0]), 3);
    let _g = tch::no_grad_guard();
    let s = warm(&m, 1, 4);
    let actions = Tensor::from_slice(&[-1.0f32, -1.0, 0.0, 0.5, 1.0, -0.3, 0.9, 0.9]).view([4, 2]);
    let cands = m.predict_candidates(&s, &actions);
    assert_eq!(cands.size(), [4, 1, 8, 12]);
    let frame = Tensor::rand([1, 1, 8, 12], F);
    for k in 0..4 {
        let (_, out) = m.step(&s, &frame, &actions.narrow(0, k, 1));
        let diff = (&out.prediction - cands.narrow(0, k, 1))
            .abs()
            .max()
            .double_value(&[]);
        assert!(
            diff < 1e-5,
            "candidate {k} differs from a single step by {diff}"
        );
    }
    let rowwise = m.predict_candidates(&s.expand(4), &actions);
    let diff = (&rowwise - &cands).abs().max().double_value(&[]);
    assert!(
        diff < 1e-5,
        "shared-work path differs from the expanded state by {diff}"
    );
    let spread = (cands.narrow(0, 0, 1) - cands.narrow(0, 3, 1))
        .abs()
        .max()
        .double_value(&[]);
    assert!(
        spread > 1e-4,
        "the prediction must depend on the action (spread {spread})"
    );
}

#[test]
fn each_gu_keeps_its_own_state() {
    let (_vs, m) = build(&small([1.0, 1.3, 2.0]), 4);
    let _g = tch::no_grad_guard();
    let s = warm(&m, 2, 4);
    for (l, layer) in s.layers.iter().enumerate() {
        let (a, b) = (&layer.h.select(1, 0 as i64), &layer.h.select(1, 1 as i64));
        let diff = (a - b).abs().max().double_value(&[]);
        assert!(
            diff > 1e-3,
            "layer {l}: GU 0 and GU 1 collapsed (max diff {diff})"
        );
        assert_ne!(
            a.data_ptr(),
            b.data_ptr(),
            "layer {l}: GU states alias one buffer"
        );
        let cdiff = (&layer.c.select(1, 0 as i64) - &layer.c.select(1, 1 as i64))
            .abs()
            .max()
            .double_value(&[]);
        assert!(cdiff > 1e-3, "layer {l}: cell states collapsed");
    }
}

/// R^d_l(t) recomputed by hand from the previous state with the unit's own ConvLSTM.
fn manual_unit(m: &MtaPredNet, prev: &State, next: &State, l: usize, d: usize) -> (Tensor, Tensor) {
    let layer = &m.layers[l];
    let p = &prev.layers[l];
    let x = match next.layers.get(l + 1) {
        Some(above) => {
            let (h, w) = (p.e.size()[2], p.e.size()[3]);
            Tensor::cat(&[&p.e, &above.r.upsample_nearest2d([h, w], None, None)], 1)
        }
        None => p.e.shallow_clone(),
    };
    mtanet_models::reference::unit(
        layer,
        d as i64,
        &x,
        &p.h.select(1, d as i64),
        &p.c.select(1, d as i64),
    )
}

#[test]
fn tau_one_is_the_plain_recurrent_update_and_tau_leaks() {
    let _g = tch::no_grad_guard();
    let (_vs, plain) = build(&small([1.0, 1.0, 1.0]), 5);
    let prev = warm(&plain, 2, 3);
    let (next, _) = plain.step(
        &prev,
        &Tensor::rand([2, 1, 8, 12], F),
        &Tensor::rand([2, 2], F),
    );
    for l in 0..3 {
        for d in 0..2 {
            let (h, c) = manual_unit(&plain, &prev, &next, l, d);
            // The fused convolution sums in another order: equal to float rounding.
            let off = |a: &Tensor, b: Tensor| (a - b).abs().max().double_value(&[]);
            assert!(
                off(&h, next.layers[l].h.select(1, d as i64)) < 1e-6,
                "tau = 1, layer {l} GU {d}: h is not the ConvLSTM's"
            );
            assert!(
                off(&c, next.layers[l].c.select(1, d as i64)) < 1e-6,
                "tau = 1, layer {l} GU {d}: c is not the ConvLSTM's"
            );
        }
    }
    let (_vs, leaky) = build(&small([1.0, 1.3, 2.0]), 5);
    let prev = warm(&leaky, 2, 3);
    let (next, _) = leaky.step(
        &prev,
        &Tensor::rand([2, 1, 8, 12], F),
        &Tensor::rand([2, 2], F),
    );
    for (l, tau) in [(1usize, 1.3f64), (2, 2.0)] {
        let (h, c) = manual_unit(&leaky, &prev, &next, l, 0);
        let want_h = &prev.layers[l].h.select(1, 0 as i64) * (1.0 - 1.0 / tau) + h * (1.0 / tau);
        let want_c = &prev.layers[l].c.select(1, 0 as i64) * (1.0 - 1.0 / tau) + c * (1.0 / tau);
        let dh = (want_h - &next.layers[l].h.select(1, 0 as i64))
            .abs()
            .max()
            .double_value(&[]);
        let dc = (want_c - &next.layers[l].c.select(1, 0 as i64))
            .abs()
            .max()
            .double_value(&[]);
        assert!(
            dh < 1e-6 && dc < 1e-6,
            "tau {tau}: leaky update off by {dh} / {dc}"
        );
    }
    assert_eq!(
        leaky.layers.iter().map(PredLayer::tau).collect::<Vec<_>>(),
        [1.0, 1.3, 2.0]
    );
}

#[test]
fn r_is_the_action_weighted_sum_of_the_units() {
    let _g = tch::no_grad_guard();
    let (_vs, m) = build(&small([1.0, 1.3, 2.0]), 6);
    let prev = warm(&m, 2, 2);
    let action = Tensor::rand([2, 2], F);
    let (next, _) = m.step(&prev, &Tensor::rand([2, 1, 8, 12], F), &action);
    for l in 0..3 {
        let w = m.layers[l].action_mlp.forward(&action); // [B, G]
        let ls = &next.layers[l];
        let want = &ls.h.select(1, 0 as i64) * w.narrow(1, 0, 1).view([2, 1, 1, 1])
            + &ls.h.select(1, 1 as i64) * w.narrow(1, 1, 1).view([2, 1, 1, 1]);
        let diff = (want - &ls.r).abs().max().double_value(&[]);
        assert!(diff < 1e-6, "layer {l}: R is not sum_d w_d h_d ({diff})");
    }
}

#[test]
fn state_expand_detach_and_select() {
    let (_vs, m) = build(&small([1.0, 1.3, 2.0]), 7);
    let s = warm(&m, 1, 2);
    let k = s.expand(5);
    assert_eq!(
        (k.batch(), k.layers[1].h.select(1, 0 as i64).size()[0]),
        (5, 5)
    );
    assert!(k.layers[0].r.get(4).equal(&s.layers[0].r.get(0)));
    let picked = k.select(&Tensor::from_slice(&[2i64]));
    assert!(
        picked.layers[2]
            .c
            .select(1, 1 as i64)
            .equal(&s.layers[2].c.select(1, 1 as i64))
    );
    assert!(
        !s.detach().layers[0].h.select(1, 0 as i64).requires_grad(),
        "detach cuts the graph"
    );
    let two = warm(&m, 2, 1).expand(3);
    assert_eq!(two.batch(), 6, "batch 2 repeats each element K times");
}
