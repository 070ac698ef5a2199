//! The straightforward form of MTA-PredNet, written from the equations one unit, one layer and
//! one step at a time, on the same parameters as the fast form in `model.rs`/`layer.rs`. Not
//! used to run anything: the exactness tests and the benchmark's baseline compare against it.
//!
//! Per layer l and step t: every unit d runs its own ConvLSTM on [E_l(t-1), up(R_{l+1}(t)),
//! h_d(t-1)] with its own rows of the weights; h_d and c_d are blended with tau; R_l(t) =
//! sum_d MLP_l(a(t))_d h_d; Xhat_l = relu(conv(R_l)); E_l = [relu(X_l - Xhat_l); relu(Xhat_l -
//! X_l)]; X_{l+1} = maxpool(relu(conv(E_l))). Imagination takes Xhat_0 as X_0.

use crate::MtaPredNet;
use crate::layer::PredLayer;
use crate::state::{LayerState, State};
use tch::{Kind, Tensor, nn::Module};

/// One unit's ConvLSTM update: `(h', c')` from the shared input `x`, and its own `h`, `c`.
pub fn unit(layer: &PredLayer, d: i64, x: &Tensor, h: &Tensor, c: &Tensor) -> (Tensor, Tensor) {
    let u = &layer.units;
    let rows = 4 * u.hidden;
    let w = Tensor::cat(
        &[
            u.wx.narrow(0, d * rows, rows),
            u.wh.narrow(0, d * rows, rows),
        ],
        1,
    );
    let b = u.bias.narrow(0, d * rows, rows);
    let pad = [u.padding, u.padding];
    let gates = Tensor::cat(&[x, h], 1).conv2d(&w, Some(&b), [1, 1], pad, [1, 1], 1);
    let g: Vec<Tensor> = gates.chunk(4, 1);
    let (i, f, o, gg) = (g[0].sigmoid(), g[1].sigmoid(), g[2].sigmoid(), g[3].tanh());
    let c_new = &f * c + &i * &gg;
    let h_new = &o * c_new.tanh();
    (h_new, c_new)
}

fn leak(tau: f64, old: &Tensor, new: &Tensor) -> Tensor {
    old * (1.0 - 1.0 / tau) + new * (1.0 / tau)
}

/// One step of the network, observed (`frame` `[B, 1, H, W]`) or imagined (`None`). Returns
/// the new state and Xhat_0.
pub fn step(
    model: &MtaPredNet,
    state: &State,
    frame: Option<&Tensor>,
    action: &Tensor,
) -> (State, Tensor) {
    let n = model.layers.len();
    let mut hs: Vec<Tensor> = Vec::new();
    let mut cs: Vec<Tensor> = Vec::new();
    let mut rs: Vec<Option<Tensor>> = (0..n).map(|_| None).collect();
    let mut hc: Vec<Option<(Tensor, Tensor)>> = (0..n).map(|_| None).collect();
    for l in (0..n).rev() {
        let layer = &model.layers[l];
        let prev = &state.layers[l];
        let x = match &rs.get(l + 1).and_then(Option::as_ref) {
            Some(r) => Tensor::cat(
                &[
                    &prev.e,
                    &r.upsample_nearest2d([layer.size().0, layer.size().1], None, None),
                ],
                1,
            ),
            None => prev.e.shallow_clone(),
        };
        let weights = layer.action_mlp.forward(action);
        hs.clear();
        cs.clear();
        let mut r: Option<Tensor> = None;
        for d in 0..layer.unit_count() {
            let (h_old, c_old) = (prev.h.select(1, d), prev.c.select(1, d));
            let (h_new, c_new) = unit(layer, d, &x, &h_old, &c_old);
            let h = leak(layer.tau(), &h_old, &h_new);
            let c = leak(layer.tau(), &c_old, &c_new);
            let term = &h * weights.select(1, d).view([-1, 1, 1, 1]);
            r = Some(match r {
                Some(acc) => acc + term,
                None => term,
            });
            hs.push(h);
            cs.push(c);
        }
        rs[l] = r;
        hc[l] = Some((Tensor::stack(&hs, 1), Tensor::stack(&cs, 1)));
    }
    let mut layers = Vec::with_capacity(n);
    let mut below: Option<Tensor> = None;
    let mut prediction = None;
    for (l, (layer, (r, hc))) in model.layers.iter().zip(rs.into_iter().zip(hc)).enumerate() {
        let r = r.expect("every layer has a unit");
        let xhat = layer.xhat.forward(&r).relu();
        let target = if l == 0 {
            frame.map_or_else(|| xhat.shallow_clone(), Tensor::shallow_clone)
        } else {
            let conv = layer.input.as_ref().expect("an input conv above layer 0");
            conv.forward(below.as_ref().expect("E below"))
                .relu()
                .max_pool2d([2, 2], [2, 2], [0, 0], [1, 1], false)
        };
        let e = Tensor::cat(&[(&target - &xhat).relu(), (&xhat - &target).relu()], 1);
        if l == 0 {
            prediction = Some(xhat);
        }
        below = Some(e.shallow_clone());
        let (h, c) = hc.expect("every layer ran");
        layers.push(LayerState { h, c, r, e });
    }
    let state = State {
        layers,
        imagined: frame.is_none(),
    };
    (state, prediction.expect("at least one layer"))
}

/// A sequence `[B, T, 1, H, W]` with actions `[B, T, A]` from `state`, the first `observed`
/// frames seen and the rest imagined; returns Xhat_0 `[B, T, 1, H, W]` and the layer-0 loss
/// terms as `MtaPredNet::f_forward_sequence_imagining` scores them (MSE per sample and step,
/// `[B, T]`), and the final state.
pub fn sequence(
    model: &MtaPredNet,
    state: &State,
    frames: &Tensor,
    actions: &Tensor,
    observed: i64,
) -> (Tensor, Tensor, State) {
    let t = frames.size()[1];
    let mut state = state.shallow_clone();
    let (mut preds, mut errs) = (Vec::new(), Vec::new());
    for i in 0..t {
        let frame = frames.select(1, i);
        let seen = (i < observed).then_some(&frame);
        let (next, pred) = step(model, &state, seen, &actions.select(1, i));
        errs.push(
            (&pred - &frame)
                .square()
                .mean_dim(&[1, 2, 3][..], false, Kind::Float),
        );
        preds.push(pred);
        state = next;
    }
    (Tensor::stack(&preds, 1), Tensor::stack(&errs, 1), state)
}
