//! One generative unit: a convolutional LSTM cell (Shi et al. 2015, PredNet's variant without
//! peepholes: the gates see the input and h, not c).

use tch::{Tensor, nn};

/// A ConvLSTM cell whose four gates come from one convolution over `[input, h]`.
#[derive(Debug)]
pub struct ConvLstm {
    conv: nn::Conv2D,
    hidden: i64,
}

impl ConvLstm {
    /// `input` channels are everything but h (E_l and the top-down R_{l+1}); `hidden` is R's width.
    pub fn new(p: &nn::Path, input: i64, hidden: i64, kernel: i64) -> Self {
        let cfg = nn::ConvConfig {
            padding: kernel / 2,
            ..Default::default()
        };
        let conv = nn::conv2d(p / "conv", input + hidden, 4 * hidden, kernel, cfg);
        // Forget-gate bias 1: the cell starts by keeping its memory, the usual LSTM remedy for
        // gradients vanishing through time in the first updates.
        if let Some(bias) = &conv.bs {
            tch::no_grad(|| {
                let _ = bias.narrow(0, hidden, hidden).fill_(1.0);
            });
        }
        Self { conv, hidden }
    }

    /// Width of h and c.
    pub fn hidden(&self) -> i64 {
        self.hidden
    }

    /// One plain (non-leaky) update: `(h', c')` from `x` (inputs without h), `h` and `c`.
    pub fn forward(&self, x: &Tensor, h: &Tensor, c: &Tensor) -> (Tensor, Tensor) {
        let gates = Tensor::cat(&[x, h], 1).apply(&self.conv);
        // Order i, f, o, g: i/f/o squashed with one sigmoid call over their 3 blocks.
        let ifo = gates
            .narrow(1, 0, 3 * self.hidden)
            .sigmoid()
            .split(self.hidden, 1);
        let g = gates.narrow(1, 3 * self.hidden, self.hidden).tanh();
        let c_new = &ifo[1] * c + &ifo[0] * g;
        let h_new = &ifo[2] * c_new.tanh();
        (h_new, c_new)
    }
}
