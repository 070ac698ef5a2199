//! One generative unit: a convolutional LSTM cell (Shi et al. 2015, PredNet's variant without
//! peepholes: the gates see the input and h, not c).

use tch::{Tensor, nn};

/// A ConvLSTM cell whose four gates come from one convolution over `[input, h]`.
#[derive(Debug)]
pub struct ConvLstm {
    conv: nn::Conv2D,
    hidden: i64,
    padding: i64,
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
        Self {
            conv,
            hidden,
            padding: kernel / 2,
        }
    }

    /// Width of h and c.
    pub fn hidden(&self) -> i64 {
        self.hidden
    }

    /// One plain (non-leaky) update: `(h', c')` from `x` (inputs without h), `h` and `c`.
    pub fn forward(&self, x: &Tensor, h: &Tensor, c: &Tensor) -> (Tensor, Tensor) {
        self.cell(&Tensor::cat(&[x, h], 1).apply(&self.conv), c)
    }

    /// The same update with the input split as `x = [fixed, varying]`, where `fixed`, `h` and `c`
    /// have batch 1 and `varying` batch K. The convolution is linear, so the gates are
    /// conv([fixed, h]) + conv(varying): the first is computed once and broadcast over the K
    /// candidates, which then pay only for the varying (top-down) channels.
    pub fn forward_split(
        &self,
        fixed: &Tensor,
        varying: &Tensor,
        h: &Tensor,
        c: &Tensor,
    ) -> (Tensor, Tensor) {
        let (nf, nv) = (fixed.size()[1], varying.size()[1]);
        let w = &self.conv.ws;
        let w_fixed = Tensor::cat(&[w.narrow(1, 0, nf), w.narrow(1, nf + nv, self.hidden)], 1);
        let pad = [self.padding, self.padding];
        let shared = Tensor::cat(&[fixed, h], 1).conv2d(
            &w_fixed,
            self.conv.bs.as_ref(),
            [1, 1],
            pad,
            [1, 1],
            1,
        );
        let per_candidate =
            varying.conv2d(&w.narrow(1, nf, nv), None::<Tensor>, [1, 1], pad, [1, 1], 1);
        self.cell(&(per_candidate + shared), c)
    }

    /// LSTM cell from the gate pre-activations, in the order i, f, o, g.
    fn cell(&self, gates: &Tensor, c: &Tensor) -> (Tensor, Tensor) {
        // i/f/o squashed with one sigmoid call over their 3 blocks.
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
