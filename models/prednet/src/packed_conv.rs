//! Inference convolutions at small batch: im2col in Rust and faer's matrix product, in place of
//! libtorch's convolution.
//!
//! At batch 1 on these 8x12 maps libtorch runs im2col and MKL's sgemm, and MKL takes its
//! generic code path on AMD CPUs: a unit convolution of the default network cost 50-200 us
//! where this costs 20-30 us (docs/measurements.md, "Model throughput"). Same sums, other order:
//! results agree with libtorch's to float rounding (tests/exactness.rs). No autograd: only for
//! weights that are not being trained.

use tch::{Device, Kind, Tensor};

/// A "same"-padded, stride-1 convolution with odd square kernel, its weights packed for the
/// product: `wt` is `[cin * k * k, cout]`, output channel fastest.
#[derive(Debug)]
pub struct PackedConv {
    wt: Vec<f32>,
    bias: Option<Vec<f32>>,
    cin: usize,
    cout: usize,
    k: usize,
}

/// Up to this batch the packed form is used: from batch 4 on libtorch's (oneDNN's) grouped
/// convolutions were as fast or faster (a K = 16 x 15 rollout 21 ms with them, 27 ms packed).
pub const MAX_BATCH: i64 = 3;

fn to_vec(t: &Tensor) -> Vec<f32> {
    Vec::<f32>::try_from(
        &t.detach()
            .to_kind(Kind::Float)
            .to_device(Device::Cpu)
            .flatten(0, -1),
    )
    .expect("a float tensor converts to Vec<f32>")
}

impl PackedConv {
    /// From a weight `[cout, cin, k, k]` and optional bias `[cout]`.
    pub fn new(weight: &Tensor, bias: Option<&Tensor>) -> Self {
        let s = weight.size();
        assert!(
            s.len() == 4 && s[2] == s[3] && s[2] % 2 == 1,
            "PackedConv: weight {s:?} is not [cout, cin, k, k] with odd k"
        );
        let (cout, cin, k) = (s[0] as usize, s[1] as usize, s[2] as usize);
        Self {
            wt: to_vec(&weight.reshape([s[0], -1]).transpose(0, 1)),
            bias: bias.map(to_vec),
            cin,
            cout,
            k,
        }
    }

    /// `x` `[B, cin, H, W]` (float, CPU; gradients are not tracked) -> `[B, cout, H, W]`.
    pub fn forward(&self, x: &Tensor) -> Tensor {
        let s = x.size();
        assert!(
            s.len() == 4 && s[1] as usize == self.cin,
            "PackedConv: input {s:?}, expected [B, {}, H, W]",
            self.cin
        );
        assert_eq!(x.kind(), Kind::Float, "PackedConv: input must be float32");
        let x = x.to_device(Device::Cpu).contiguous();
        let (b, h, w) = (s[0] as usize, s[2] as usize, s[3] as usize);
        let (hw, kk) = (h * w, self.cin * self.k * self.k);
        // SAFETY: `x` is a contiguous CPU float tensor of b * cin * hw elements that lives
        // until the end of this function.
        let input =
            unsafe { std::slice::from_raw_parts(x.data_ptr() as *const f32, b * self.cin * hw) };
        // cols [kk, b * hw]: every sample's columns side by side, so one product covers the batch.
        let n = b * hw;
        let mut cols = vec![0f32; kk * n];
        for i in 0..b {
            im2col(
                &input[i * self.cin * hw..][..self.cin * hw],
                self.cin,
                h,
                w,
                self.k,
                &mut cols,
                n,
                i * hw,
            );
        }
        // prod [cout, n], column-major (output channel fastest), starts at the bias.
        let mut prod = vec![0f32; self.cout * n];
        if let Some(bias) = &self.bias {
            for col in prod.chunks_exact_mut(self.cout) {
                col.copy_from_slice(bias);
            }
        }
        let accum = if self.bias.is_some() {
            faer::Accum::Add
        } else {
            faer::Accum::Replace
        };
        // SAFETY: the three views cover exactly the buffers above, with the strides they were
        // laid out with.
        unsafe {
            let lhs = faer::MatRef::<f32>::from_raw_parts(
                self.wt.as_ptr(),
                self.cout,
                kk,
                1,
                self.cout as isize,
            );
            let rhs = faer::MatRef::<f32>::from_raw_parts(cols.as_ptr(), kk, n, n as isize, 1);
            let dst = faer::MatMut::<f32>::from_raw_parts_mut(
                prod.as_mut_ptr(),
                self.cout,
                n,
                1,
                self.cout as isize,
            );
            faer::linalg::matmul::matmul(dst, accum, lhs, rhs, 1.0f32, faer::Par::Seq);
        }
        // To NCHW: out[i, c, p] = prod[c, i * hw + p].
        let out_t = Tensor::empty(
            [s[0], self.cout as i64, s[2], s[3]],
            (Kind::Float, Device::Cpu),
        );
        // SAFETY: a fresh contiguous tensor of b * cout * hw floats; every element is written below.
        let out = unsafe {
            std::slice::from_raw_parts_mut(out_t.data_ptr() as *mut f32, b * self.cout * hw)
        };
        for (j, col) in prod.chunks_exact(self.cout).enumerate() {
            let (i, p) = (j / hw, j % hw);
            let base = i * self.cout * hw + p;
            for (c, v) in col.iter().enumerate() {
                out[base + c * hw] = *v;
            }
        }
        out_t
    }
}

/// Writes the k x k neighbourhoods of one sample `x` `[c, h, w]` (zero outside) into `cols`
/// (row stride `n`) at columns `col0..col0 + h * w`: row (ci, kh, kw), column position.
#[allow(clippy::too_many_arguments)]
fn im2col(
    x: &[f32],
    c: usize,
    h: usize,
    w: usize,
    k: usize,
    cols: &mut [f32],
    n: usize,
    col0: usize,
) {
    let p = (k / 2) as isize;
    let hw = h * w;
    for ci in 0..c {
        let plane = &x[ci * hw..][..hw];
        for kh in 0..k {
            for kw in 0..k {
                let row = &mut cols[((ci * k + kh) * k + kw) * n + col0..][..hw];
                let (dy, dx) = (kh as isize - p, kw as isize - p);
                let d = dx.unsigned_abs().min(w);
                for oh in 0..h {
                    let ih = oh as isize + dy;
                    let dst = &mut row[oh * w..][..w];
                    if ih < 0 || ih >= h as isize {
                        continue; // cols starts zeroed
                    }
                    let src = &plane[ih as usize * w..][..w];
                    if dx >= 0 {
                        dst[..w - d].copy_from_slice(&src[d..]);
                    } else {
                        dst[d..].copy_from_slice(&src[..w - d]);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_libtorch_convolution_for_every_batch_kernel_and_bias() {
        let _g = tch::no_grad_guard();
        tch::manual_seed(7);
        let f = (Kind::Float, Device::Cpu);
        for (b, cin, cout, h, w, k, bias) in [
            (1, 34, 64, 8, 12, 3, true),
            (1, 96, 256, 2, 3, 3, false),
            (3, 5, 7, 4, 6, 3, true),
            (16, 8, 1, 8, 12, 3, true),
            (2, 3, 4, 5, 7, 5, true),
            (1, 2, 3, 1, 1, 3, false),
        ] {
            let x = Tensor::randn([b, cin, h, w], f);
            let wt = Tensor::randn([cout, cin, k, k], f) * 0.1;
            let bs = bias.then(|| Tensor::randn([cout], f));
            let want = x.conv2d(&wt, bs.as_ref(), [1, 1], [k / 2, k / 2], [1, 1], 1);
            let got = PackedConv::new(&wt, bs.as_ref()).forward(&x);
            assert_eq!(got.size(), want.size());
            let diff = (&got - &want).abs().max().double_value(&[]);
            assert!(
                diff < 1e-5,
                "b {b} {cin}->{cout} {h}x{w} k {k}: max diff {diff}"
            );
        }
    }

    #[test]
    #[should_panic(expected = "expected [B, 4, H, W]")]
    fn refuses_an_input_with_other_channels() {
        let f = (Kind::Float, Device::Cpu);
        let conv = PackedConv::new(&Tensor::zeros([2, 4, 3, 3], f), None);
        let _ = conv.forward(&Tensor::zeros([1, 3, 8, 12], f));
    }
}
