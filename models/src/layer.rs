//! One MTA-PredNet layer: its generative units, action MLP, Xhat conv and (above layer 0) the
//! conv that turns the layer below's errors into this layer's target X_l.

use crate::config::{ActionWeighting, ModelConfig};
use crate::convlstm::ConvLstm;
use crate::state::LayerState;
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

#[derive(Debug)]
pub struct PredLayer {
    /// The generative units, at `layer{l}/gu{d}`.
    pub gus: Vec<ConvLstm>,
    pub action_mlp: ActionMlp,
    /// R_l -> Xhat_l, at `layer{l}/xhat`.
    pub xhat: nn::Conv2D,
    /// E_{l-1} -> X_l before pooling, at `layer{l}/input`; `None` at layer 0 (X_0 is the image).
    pub input: Option<nn::Conv2D>,
    tau: f64,
    channels: i64,
    a_channels: i64,
    size: (i64, i64),
    /// Where the weights live (the VarStore's device): states are made there too.
    device: tch::Device,
}

impl PredLayer {
    pub fn new(p: &nn::Path, cfg: &ModelConfig, l: usize) -> Self {
        let p = p / format!("layer{l}");
        let k = cfg.kernel;
        let (r, a) = (cfg.channels[l], cfg.a_channels[l]);
        let above = cfg.channels.get(l + 1).copied().unwrap_or(0);
        let gus = (0..cfg.gus[l])
            .map(|d| ConvLstm::new(&(&p / format!("gu{d}")), 2 * a + above, r, k))
            .collect();
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
            gus,
            action_mlp,
            xhat,
            input,
            tau: cfg.tau[l],
            channels: r,
            a_channels: a,
            size: cfg.layer_size(l),
            device: p.device(),
        }
    }

    /// Zero state for batch `b` (PredNet starts from zeros; the t = 0 prediction gets no loss).
    pub fn zero_state(&self, b: i64) -> LayerState {
        let (h, w) = self.size;
        let z = |c| Tensor::zeros([b, c, h, w], (tch::Kind::Float, self.device));
        let n = self.gus.len();
        LayerState {
            h: (0..n).map(|_| z(self.channels)).collect(),
            c: (0..n).map(|_| z(self.channels)).collect(),
            r: z(self.channels),
            e: z(2 * self.a_channels),
        }
    }

    /// Top-down half of a step: every unit's leaky update from E_l(t-1), its own state and the
    /// upsampled R_{l+1}(t), then R_l(t) weighted by the action. Returns (h, c, R_l(t)).
    pub fn top_down(
        &self,
        prev: &LayerState,
        above: Option<&Tensor>,
        action: &Tensor,
    ) -> (Vec<Tensor>, Vec<Tensor>, Tensor) {
        let x = match above {
            Some(r) => Tensor::cat(
                &[
                    &prev.e,
                    &r.upsample_nearest2d([self.size.0, self.size.1], None, None),
                ],
                1,
            ),
            None => prev.e.shallow_clone(),
        };
        let mut hs = Vec::with_capacity(self.gus.len());
        let mut cs = Vec::with_capacity(self.gus.len());
        for ((gu, h), c) in self.gus.iter().zip(&prev.h).zip(&prev.c) {
            let (h_new, c_new) = gu.forward(&x, h, c);
            hs.push(self.integrate(h, h_new));
            cs.push(self.integrate(c, c_new));
        }
        let r = self.mix(&hs, action);
        (hs, cs, r)
    }

    /// [`Self::top_down`] for K candidate actions from a batch-1 state: `above` is R_{l+1}(t) for
    /// each candidate (`[K, ...]`), or `None` at the top. Only the action-dependent work runs K
    /// times: the top layer's units do not see a(t) at all (only its weights do), and below it
    /// only the top-down channels of each unit's convolution differ between candidates.
    pub fn top_down_candidates(
        &self,
        prev: &LayerState,
        above: Option<&Tensor>,
        actions: &Tensor,
    ) -> Tensor {
        let hs: Vec<Tensor> = self
            .gus
            .iter()
            .zip(&prev.h)
            .zip(&prev.c)
            .map(|((gu, h), c)| {
                let (h_new, _) = match above {
                    Some(r) => {
                        let up = r.upsample_nearest2d([self.size.0, self.size.1], None, None);
                        gu.forward_split(&prev.e, &up, h, c)
                    }
                    None => gu.forward(&prev.e, h, c),
                };
                self.integrate(h, h_new)
            })
            .collect();
        self.mix(&hs, actions)
    }

    /// Leaky integration with tau: (1 - 1/tau) old + (1/tau) new.
    fn integrate(&self, old: &Tensor, new: Tensor) -> Tensor {
        // tau = 1 skips the blend so the plain recurrent update is exact, not just close.
        if self.tau == 1.0 {
            return new;
        }
        // Applied to the whole unit state (h and c), as the reference does: the unit's memory,
        // not only its output, moves at the layer's timescale.
        old * (1.0 - 1.0 / self.tau) + new * (1.0 / self.tau)
    }

    /// R_l = sum_d w_d(a) h_d; h_d may have batch 1 and the actions batch K (broadcast).
    fn mix(&self, hs: &[Tensor], action: &Tensor) -> Tensor {
        let w = self.action_mlp.forward(action); // [B, G]
        let b = w.size()[0];
        let stacked = Tensor::stack(hs, 1); // [B or 1, G, C, H, W]
        (stacked * w.view([b, -1, 1, 1, 1])).sum_dim_intlist(1, false, None)
    }

    /// Xhat_l = relu(conv(R_l)).
    pub fn predict(&self, r: &Tensor) -> Tensor {
        self.xhat.forward(r).relu()
    }

    /// X_l from E_{l-1}: maxpool(relu(conv(E_{l-1}))). Only for l > 0.
    pub fn target_from_below(&self, e_below: &Tensor) -> Option<Tensor> {
        let conv = self.input.as_ref()?;
        Some(
            conv.forward(e_below)
                .relu()
                .max_pool2d([2, 2], [2, 2], [0, 0], [1, 1], false),
        )
    }

    /// E_l = [relu(X - Xhat); relu(Xhat - X)].
    pub fn error(x: &Tensor, xhat: &Tensor) -> Tensor {
        let d = x - xhat;
        Tensor::cat(&[d.relu(), d.neg().relu()], 1)
    }

    pub fn tau(&self) -> f64 {
        self.tau
    }
}
