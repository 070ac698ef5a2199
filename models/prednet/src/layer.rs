//! One MTA-PredNet layer: its generative units, action MLP, Xhat conv and (above layer 0) the
//! conv that turns the layer below's errors into this layer's target X_l.
//!
//! The fast form: the units run as one convolution ([`Units`]) on weights assembled once per
//! sequence or weights version ([`LayerWeights`]), the action weights of a whole sequence come
//! from one MLP call, and an imagined step (E_0 = 0) skips what a zero input cannot change.

use crate::config::{ActionWeighting, ModelConfig};
use crate::packed_conv::{self, PackedConv};
use crate::state::LayerState;
use crate::units::Units;
use tch::{Tensor, nn, nn::Module};

/// Maps a(t) to one weight per generative unit. A trained parameter at `layer{l}/action_mlp`
/// (the reference code built its `nn.Linear` inside `forward()`, so it was never trained).
#[derive(Debug)]
pub struct ActionMlp {
    pub fc1: nn::Linear,
    pub fc2: nn::Linear,
    weighting: ActionWeighting,
    /// Fixed input normalisation (a - offset) / scale from the config; not trained.
    norm: Option<(Tensor, Tensor)>,
}

impl ActionMlp {
    pub fn new(p: &nn::Path, cfg: &ModelConfig, gus: i64) -> Self {
        let fc1 = nn::linear(
            p / "fc1",
            cfg.action_dim,
            cfg.action_hidden,
            Default::default(),
        );
        let fc2 = nn::linear(p / "fc2", cfg.action_hidden, gus, Default::default());
        let norm = (!cfg.action_offset.is_empty() || !cfg.action_scale.is_empty()).then(|| {
            let n = cfg.action_dim as usize;
            let pick = |v: &[f64], default: f64| {
                let v: Vec<f32> = (0..n)
                    .map(|i| v.get(i).copied().unwrap_or(default) as f32)
                    .collect();
                Tensor::from_slice(&v).view([1, -1])
            };
            (pick(&cfg.action_offset, 0.0), pick(&cfg.action_scale, 1.0))
        });
        Self {
            fc1,
            fc2,
            weighting: cfg.action_weighting,
            norm,
        }
    }

    /// `[B, A]` -> `[B, G]` weights.
    pub fn forward(&self, action: &Tensor) -> Tensor {
        let z = match &self.norm {
            Some((offset, scale)) => ((action - offset) / scale).apply(&self.fc1),
            None => action.apply(&self.fc1),
        };
        // tanh: actions are signed, and a bounded hidden layer keeps the gates from saturating
        // on an unusually large action.
        let z = z.tanh().apply(&self.fc2);
        match self.weighting {
            ActionWeighting::Sigmoid => z.sigmoid(),
            ActionWeighting::Softmax => z.softmax(-1, z.kind()),
        }
    }
}

/// From this batch size on, a step runs the units' h columns as a grouped convolution (exact
/// work) instead of the one block-diagonal convolution (fewer ops, G x the h work): small
/// batches are bound by op dispatch, large ones by arithmetic (benches/model.rs).
const GROUPED_FROM_BATCH: i64 = 4;
/// ... and from this R width: below it the h columns' wasted work (G - 1 of G blocks are
/// zeros) costs less than a second convolution, its backward and the sum (training update
/// ~4% faster with layer 0 fused, both networks; ~4% slower with layer 1's 16 channels fused).
const GROUPED_FROM_CHANNELS: i64 = 16;

#[derive(Debug)]
pub struct PredLayer {
    /// The generative units, at `layer{l}.units`.
    pub units: Units,
    pub action_mlp: ActionMlp,
    /// R_l -> Xhat_l, at `layer{l}/xhat`.
    pub xhat: nn::Conv2D,
    /// E_{l-1} -> X_l before pooling, at `layer{l}/input`; `None` at layer 0 (X_0 is the image).
    pub input: Option<nn::Conv2D>,
    tau: f64,
    channels: i64,
    a_channels: i64,
    above: i64,
    size: (i64, i64),
    /// Where the weights live (the VarStore's device): states are made there too.
    device: tch::Device,
}

/// Weights derived from a layer's parameters for stepping: the units' one convolution and its
/// column blocks. Derived, not stored: build again after the parameters change.
#[derive(Debug)]
pub struct LayerWeights {
    /// `[G*4C, E + up + G*C, k, k]`.
    w: Tensor,
    /// The same without the E columns, at layer 0 only (a step after an imagined one: E_0 = 0).
    w_no_e: Option<Tensor>,
    /// X_l when E_{l-1} = 0: maxpool(relu(conv(0))) = relu(bias), `[1, a, 1, 1]`.
    target_if_below_zero: Option<Tensor>,
    /// The columns of `w` a candidate step uses apart: see [`CandidateColumns`].
    cand: CandidateColumns,
    /// Every convolution of a step packed for small batches; only in inference weights.
    packed: Option<PackedLayer>,
}

/// `w` split for K candidates from one state: the top-down columns (`None` at the top), which
/// differ per candidate, and the columns every candidate shares: E and h, or h alone after an
/// imagined step.
#[derive(Debug)]
struct CandidateColumns {
    up: Option<Tensor>,
    fixed: Tensor,
    h: Tensor,
}

/// A layer's convolutions as [`PackedConv`]s (see `packed_conv.rs` for why).
#[derive(Debug)]
struct PackedLayer {
    /// The units' one convolution with its bias, and the same without the E columns (layer 0).
    units: PackedConv,
    units_no_e: Option<PackedConv>,
    /// For candidates: the top-down columns alone (no bias; `None` at the top), the E and h
    /// columns with the bias, the h columns with the bias.
    up: Option<PackedConv>,
    fixed: PackedConv,
    h_only: PackedConv,
    xhat: PackedConv,
    input: Option<PackedConv>,
}

impl LayerWeights {
    /// The packed convolutions, if these are inference weights, the batch is small enough and
    /// no input tracks gradients (the packed form would cut the graph).
    fn packed_for<T: std::borrow::Borrow<Tensor>>(
        &self,
        batch: i64,
        inputs: &[T],
    ) -> Option<&PackedLayer> {
        let p = self.packed.as_ref()?;
        let no_grad = inputs.iter().all(|t| !t.borrow().requires_grad());
        (batch <= packed_conv::MAX_BATCH && no_grad).then_some(p)
    }
}

impl PredLayer {
    pub fn new(p: &nn::Path, cfg: &ModelConfig, l: usize) -> Self {
        let p = p / format!("layer{l}");
        let k = cfg.kernel;
        let (r, a) = (cfg.channels[l], cfg.a_channels[l]);
        let above = cfg.channels.get(l + 1).copied().unwrap_or(0);
        let units = Units::new(&(&p / "units"), 2 * a + above, r, cfg.gus[l], k);
        let action_mlp = ActionMlp::new(&(&p / "action_mlp"), cfg, cfg.gus[l]);
        let conv = |bias| nn::ConvConfig {
            padding: k / 2,
            bs_init: nn::Init::Const(bias),
            ..Default::default()
        };
        let xhat = nn::conv2d(&p / "xhat", r, a, k, conv(cfg.xhat_bias[l]));
        let input =
            (l > 0).then(|| nn::conv2d(&p / "input", 2 * cfg.a_channels[l - 1], a, k, conv(0.0)));
        Self {
            units,
            action_mlp,
            xhat,
            input,
            tau: cfg.tau[l],
            channels: r,
            a_channels: a,
            above,
            size: cfg.layer_size(l),
            device: p.device(),
        }
    }

    /// The weights for stepping, from the current parameters (differentiable).
    pub fn weights(&self) -> LayerWeights {
        let w = self.units.fused();
        let e = 2 * self.a_channels;
        let cols = w.size()[1];
        let h = w.narrow(1, e + self.above, self.units.units * self.channels);
        LayerWeights {
            packed: None,
            cand: CandidateColumns {
                up: (self.above > 0).then(|| w.narrow(1, e, self.above)),
                fixed: Tensor::cat(&[&w.narrow(1, 0, e), &h], 1),
                h,
            },
            w_no_e: self
                .input
                .is_none()
                .then(|| w.narrow(1, e, cols - e).contiguous()),
            w,
            target_if_below_zero: self.input.as_ref().and_then(|c| {
                c.bs.as_ref()
                    .map(|b| b.relu().view([1, self.a_channels, 1, 1]))
            }),
        }
    }

    /// [`Self::weights`] with every convolution also packed for small batches: for inference
    /// (the packed form tracks no gradients).
    pub fn inference_weights(&self) -> LayerWeights {
        tch::no_grad(|| {
            let mut lw = self.weights();
            if self.device != tch::Device::Cpu {
                return lw; // the packed form computes on the CPU only
            }
            let bias = Some(&self.units.bias);
            let c = &lw.cand;
            lw.packed = Some(PackedLayer {
                units: PackedConv::new(&lw.w, bias),
                units_no_e: lw.w_no_e.as_ref().map(|w| PackedConv::new(w, bias)),
                up: c.up.as_ref().map(|w| PackedConv::new(w, None)),
                fixed: PackedConv::new(&c.fixed, bias),
                h_only: PackedConv::new(&c.h, bias),
                xhat: PackedConv::new(&self.xhat.ws, self.xhat.bs.as_ref()),
                input: self
                    .input
                    .as_ref()
                    .map(|c| PackedConv::new(&c.ws, c.bs.as_ref())),
            });
            lw
        })
    }

    /// Number of generative units G.
    pub fn unit_count(&self) -> i64 {
        self.units.units
    }

    /// Zero state for batch `b` (PredNet starts from zeros; the t = 0 prediction gets no loss).
    pub fn zero_state(&self, b: i64) -> LayerState {
        let (h, w) = self.size;
        let z = |s: &[i64]| Tensor::zeros(s, (tch::Kind::Float, self.device));
        let g = self.units.units;
        LayerState {
            h: z(&[b, g, self.channels, h, w]),
            c: z(&[b, g, self.channels, h, w]),
            r: z(&[b, self.channels, h, w]),
            e: z(&[b, 2 * self.a_channels, h, w]),
        }
    }

    fn up(&self, r: &Tensor) -> Tensor {
        r.upsample_nearest2d([self.size.0, self.size.1], None, None)
    }

    /// Top-down half of a step: every unit's leaky update from E_l(t-1) (skipped when
    /// `e_zero`: it is 0 after an imagined step), its own state and the upsampled R_{l+1}(t),
    /// then R_l(t) mixed with the action weights `mix` `[B, G]`. Returns (h, c, R_l(t)).
    pub fn top_down(
        &self,
        lw: &LayerWeights,
        prev: &LayerState,
        above: Option<&Tensor>,
        mix: &Tensor,
        e_zero: bool,
    ) -> (Tensor, Tensor, Tensor) {
        let mut parts = Vec::with_capacity(3);
        if !e_zero {
            parts.push(prev.e.shallow_clone());
        }
        if let Some(r) = above {
            parts.push(self.up(r));
        }
        parts.push(prev.h.flatten(1, 2));
        let packed = lw.packed_for(prev.h.size()[0], &parts);
        let gates = if let Some(p) = packed {
            let conv = match (&p.units_no_e, e_zero) {
                (Some(c), true) => c,
                _ => &p.units,
            };
            conv.forward(&Tensor::cat(&parts, 1))
        } else if prev.h.size()[0] >= GROUPED_FROM_BATCH && self.channels >= GROUPED_FROM_CHANNELS {
            // Compute-bound: the block-diagonal h columns would multiply zeros G - 1 times
            // in G; a grouped convolution over the units' own h does only the real work.
            let h = parts.pop().expect("h");
            let u = &self.units;
            let wx = if e_zero {
                u.wx.narrow(1, 2 * self.a_channels, self.above)
            } else {
                u.wx.shallow_clone()
            };
            let pad = [u.padding, u.padding];
            let x = if parts.is_empty() {
                None
            } else {
                Some(Tensor::cat(&parts, 1))
            };
            let hg = h.conv2d(&u.wh, Some(&u.bias), [1, 1], pad, [1, 1], u.units);
            match x {
                Some(x) => x.conv2d(&wx, None::<Tensor>, [1, 1], pad, [1, 1], 1) + hg,
                None => hg,
            }
        } else {
            let weight = match (&lw.w_no_e, e_zero) {
                (Some(w), true) => w,
                _ => &lw.w,
            };
            self.units
                .gates(&Tensor::cat(&parts, 1), weight, Some(&self.units.bias))
        };
        let (h_new, c_new) = self.units.cell(&gates, &prev.c);
        let h = self.integrate(&prev.h, h_new);
        let c = self.integrate(&prev.c, c_new);
        let r = Self::mix(&h, mix);
        (h, c, r)
    }

    /// [`Self::top_down`] for K candidates from a batch-1 state: `above` is R_{l+1}(t) per
    /// candidate (`[K, ...]`), or `None` at the top, and `mix` `[K, G]`. Only the
    /// action-dependent work runs K times: the top layer's units do not see a(t) at all (only
    /// their mixing does), and below it only the top-down columns of the units' convolution
    /// differ between candidates (the convolution is linear: conv([fixed, up]) = conv(fixed) +
    /// conv(up)). h and c come back with batch K, or 1 at the top.
    pub fn top_down_candidates(
        &self,
        lw: &LayerWeights,
        prev: &LayerState,
        above: Option<&Tensor>,
        mix: &Tensor,
        e_zero: bool,
    ) -> (Tensor, Tensor, Tensor) {
        let Some(r) = above else {
            return self.top_down(lw, prev, None, mix, e_zero);
        };
        let h_flat = prev.h.flatten(1, 2);
        let up = self.up(r);
        let bias = Some(&self.units.bias);
        // The shared columns at batch 1, the top-down ones at batch K: each packed if small.
        let shared = match lw.packed_for(h_flat.size()[0], &[&h_flat, &prev.e]) {
            Some(p) if e_zero => p.h_only.forward(&h_flat),
            Some(p) => p.fixed.forward(&Tensor::cat(&[&prev.e, &h_flat], 1)),
            None if e_zero => self.units.gates(&h_flat, &lw.cand.h, bias),
            None => {
                let x = Tensor::cat(&[&prev.e, &h_flat], 1);
                self.units.gates(&x, &lw.cand.fixed, bias)
            }
        };
        let from_above = match lw.packed_for(up.size()[0], &[&up]) {
            Some(p) => p.up.as_ref().expect("a layer below the top").forward(&up),
            None => {
                let w_up = lw.cand.up.as_ref().expect("a layer below the top");
                self.units.gates(&up, w_up, None)
            }
        };
        let gates = from_above + shared;
        let (h_new, c_new) = self.units.cell(&gates, &prev.c);
        let h = self.integrate(&prev.h, h_new);
        let c = self.integrate(&prev.c, c_new);
        let r = Self::mix(&h, mix);
        (h, c, r)
    }

    /// Leaky integration with tau: (1 - 1/tau) old + (1/tau) new, as one lerp.
    fn integrate(&self, old: &Tensor, new: Tensor) -> Tensor {
        // tau = 1 skips the blend so the plain recurrent update is exact, not just close.
        if self.tau == 1.0 {
            return new;
        }
        // Applied to the whole unit state (h and c), as the reference does: the unit's memory,
        // not only its output, moves at the layer's timescale. old may have batch 1 (broadcast).
        if old.size()[0] == new.size()[0] {
            old.lerp(&new, 1.0 / self.tau)
        } else {
            old.expand_as(&new).lerp(&new, 1.0 / self.tau)
        }
    }

    /// R_l = sum_d w_d h_d as one matrix product: h `[B or 1, G, C, H, W]`, w `[K, G]` (K = B,
    /// or any K from a batch-1 h).
    fn mix(h: &Tensor, w: &Tensor) -> Tensor {
        let s = h.size();
        let k = w.size()[0];
        let out = if s[0] == k {
            w.unsqueeze(1).bmm(&h.reshape([k, s[1], -1]))
        } else {
            w.mm(&h.reshape([s[1], -1]))
        };
        out.view([k, s[2], s[3], s[4]])
    }

    /// The action weights `[N, G]` of actions `[N, A]`.
    pub fn action_weights(&self, actions: &Tensor) -> Tensor {
        self.action_mlp.forward(actions)
    }

    /// Xhat_l = relu(conv(R_l)).
    pub fn predict(&self, lw: &LayerWeights, r: &Tensor) -> Tensor {
        match lw.packed_for(r.size()[0], &[r]) {
            Some(p) => p.xhat.forward(r).relu(),
            None => self.xhat.forward(r).relu(),
        }
    }

    /// X_l from E_{l-1}: maxpool(relu(conv(E_{l-1}))), or its constant when E_{l-1} = 0. Only
    /// for l > 0.
    pub fn target_from_below(&self, lw: &LayerWeights, e_below: Option<&Tensor>) -> Option<Tensor> {
        let conv = self.input.as_ref()?;
        match (e_below, &lw.target_if_below_zero) {
            (None, Some(t)) => Some(t.shallow_clone()),
            (Some(e), _) => {
                let packed = lw.packed_for(e.size()[0], &[e]);
                let z = match packed.and_then(|p| p.input.as_ref()) {
                    Some(c) => c.forward(e),
                    None => conv.forward(e),
                };
                Some(z.relu().max_pool2d([2, 2], [2, 2], [0, 0], [1, 1], false))
            }
            (None, None) => None,
        }
    }

    /// E_l = [relu(X - Xhat); relu(Xhat - X)] (X may broadcast).
    pub fn error(x: &Tensor, xhat: &Tensor) -> Tensor {
        let d = x - xhat;
        Tensor::cat(&[d.relu(), d.neg().relu()], 1)
    }

    pub fn tau(&self) -> f64 {
        self.tau
    }

    pub fn size(&self) -> (i64, i64) {
        self.size
    }
}
