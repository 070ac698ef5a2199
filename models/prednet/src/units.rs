//! The generative units of one layer: G convolutional LSTM cells (Shi et al. 2015, PredNet's
//! variant without peepholes: the gates see the input and h, not c), stored and run together.
//!
//! Every unit reads the same input (E_l(t-1) and the upsampled R_{l+1}(t)) and its own h, so the
//! G gate convolutions are one convolution with G x 4 x C output channels over
//! `[E, up(R_{l+1}), h_0, ..., h_{G-1}]` whose h columns are block-diagonal: unit d's gates see
//! only h_d. Each unit keeps its own weights (its rows) and its own state (`[B, G, C, H, W]`).
//! `reference.rs` computes the same one unit at a time, for the exactness tests.

use tch::{Kind, Tensor, nn};

/// The parameters, at `layer{l}.units.{wx,wh,bias}`. Gate order inside each unit's 4C block:
/// i, f, o, g.
#[derive(Debug)]
pub struct Units {
    /// `[G*4C, X, k, k]`: the shared input columns, E then up(R_{l+1}).
    pub wx: Tensor,
    /// `[G*4C, C, k, k]`: rows of unit d read its own h_d.
    pub wh: Tensor,
    /// `[G*4C]`.
    pub bias: Tensor,
    pub units: i64,
    pub hidden: i64,
    pub padding: i64,
}

impl Units {
    /// `inputs`: the shared input channels (E_l and the top-down R_{l+1}); `hidden`: R's width.
    pub fn new(p: &nn::Path, inputs: i64, hidden: i64, units: i64, kernel: i64) -> Self {
        // As tch's nn::conv2d initialises one unit's [4C, inputs + C] convolution: Kaiming
        // uniform for ReLU over that fan-in (bound sqrt(6 / fan_in)), zero bias.
        let fan_in = ((inputs + hidden) * kernel * kernel) as f64;
        let bound = (6.0 / fan_in).sqrt();
        let init = nn::Init::Uniform {
            lo: -bound,
            up: bound,
        };
        let rows = units * 4 * hidden;
        let wx = p.var("wx", &[rows, inputs, kernel, kernel], init);
        let wh = p.var("wh", &[rows, hidden, kernel, kernel], init);
        let bias = p.var("bias", &[rows], nn::Init::Const(0.0));
        // Forget-gate bias 1: a cell starts by keeping its memory, the usual LSTM remedy for
        // gradients vanishing through time in the first updates.
        tch::no_grad(|| {
            let _ = bias.view([units, 4, hidden]).narrow(1, 1, 1).fill_(1.0);
        });
        Self {
            wx,
            wh,
            bias,
            units,
            hidden,
            padding: kernel / 2,
        }
    }

    /// The one convolution's weight, `[G*4C, X + G*C, k, k]`: wx beside block-diagonal wh.
    /// Built once per sequence (training) or per weights version (inference), not per step.
    pub fn fused(&self) -> Tensor {
        let (g, c) = (self.units, self.hidden);
        let s = self.wh.size();
        let eye = Tensor::eye(g, (Kind::Float, self.wh.device())).view([g, 1, g, 1, 1, 1]);
        let wh = self.wh.view([g, 4 * c, 1, c, s[2], s[3]]) * eye;
        Tensor::cat(&[&self.wx, &wh.view([g * 4 * c, g * c, s[2], s[3]])], 1)
    }

    /// The gates `[B, G*4C, H, W]` from `input` (the columns of `weight`, in order) and the
    /// bias.
    pub fn gates(&self, input: &Tensor, weight: &Tensor, bias: Option<&Tensor>) -> Tensor {
        let pad = [self.padding, self.padding];
        input.conv2d(weight, bias, [1, 1], pad, [1, 1], 1)
    }

    /// The plain LSTM update of every unit from its gate pre-activations `[B, G*4C, H, W]` and
    /// cell state `c` `[B or 1, G, C, H, W]`: `(h', c')`, each `[B, G, C, H, W]`.
    pub fn cell(&self, gates: &Tensor, c: &Tensor) -> (Tensor, Tensor) {
        let s = gates.size();
        let g6 = gates.view([s[0], self.units, 4, self.hidden, s[2], s[3]]);
        // unbind: one backward node for the four blocks (a select each would scatter into a
        // zero tensor of the whole size in the backward pass).
        let parts = g6.unbind(2);
        let (i, f, o) = (parts[0].sigmoid(), parts[1].sigmoid(), parts[2].sigmoid());
        let g = tanh(&parts[3]);
        let c_new = (f * c).addcmul(&i, &g);
        let h_new = o * tanh(&c_new);
        (h_new, c_new)
    }
}

/// From this many elements tanh goes through the sigmoid, tanh(x) = 2 sigmoid(2x) - 1: here
/// libtorch's tanh (MKL's vector maths) costs ~2.2 ns an element, its sigmoid ~0.25 ns, and the
/// three extra ops ~5 us. The two agree to 2e-7.
const TANH_BY_SIGMOID_FROM: i64 = 4096;

fn tanh(x: &Tensor) -> Tensor {
    if x.numel() as i64 >= TANH_BY_SIGMOID_FROM {
        (x * 2.0).sigmoid() * 2.0 - 1.0
    } else {
        x.tanh()
    }
}
