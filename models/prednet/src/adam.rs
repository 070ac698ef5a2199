//! Adam whose moments can be saved and restored. tch's `nn::Optimizer` keeps them inside
//! libtorch with no way to read or set them, so a resumed trainer would restart its statistics;
//! this is the same update as `torch.optim.Adam` (no weight decay, no amsgrad), on tensors we own.

use crate::checkpoint::{self, Checkpoint, CheckpointError, Meta};
use crate::config::ModelConfig;
use std::collections::{BTreeMap, HashMap};
use tch::{Tensor, nn::VarStore};

/// Header format of an optimiser-state file (a sibling of the weights checkpoint).
pub const FORMAT: &str = "mtanet-optimizer";

/// First and second moment of one variable.
struct Moments {
    m: Tensor,
    v: Tensor,
}

/// Adam over the trainable variables of one VarStore.
pub struct Adam {
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
    moments: BTreeMap<String, Moments>,
}

fn trainable(vs: &VarStore) -> BTreeMap<String, Tensor> {
    vs.variables()
        .into_iter()
        .filter(|(_, t)| t.requires_grad())
        .collect()
}

impl Adam {
    /// Zero moments for every trainable variable of `vs`; torch's defaults for betas and eps.
    pub fn new(vs: &VarStore, lr: f64) -> Self {
        let moments = trainable(vs)
            .into_iter()
            .map(|(name, p)| {
                let m = Moments {
                    m: p.zeros_like(),
                    v: p.zeros_like(),
                };
                (name, m)
            })
            .collect();
        Self {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            moments,
        }
    }

    /// Clears the gradients of the trainable variables.
    pub fn zero_grad(&self, vs: &VarStore) {
        for p in trainable(vs).values() {
            let mut g = p.grad();
            if g.defined() {
                let _ = g.detach_().zero_();
            }
        }
    }

    /// One Adam step from the current gradients; `t` counts steps from 1 (bias correction).
    pub fn step(&mut self, vs: &VarStore, t: u64) {
        let t = t.max(1) as i32;
        let bias1 = 1.0 - self.beta1.powi(t);
        let bias2_sqrt = (1.0 - self.beta2.powi(t)).sqrt();
        tch::no_grad(|| {
            for (name, p) in trainable(vs) {
                let g = p.grad();
                let Some(mo) = self.moments.get_mut(&name).filter(|_| g.defined()) else {
                    continue;
                };
                let _ =
                    mo.m.g_mul_scalar_(self.beta1)
                        .g_add_(&(&g * (1.0 - self.beta1)));
                let _ =
                    mo.v.g_mul_scalar_(self.beta2)
                        .g_add_(&(&g * &g * (1.0 - self.beta2)));
                let denom = mo.v.sqrt() / bias2_sqrt + self.eps;
                let mut p = p;
                let _ = p.g_sub_(&(&mo.m / denom * (self.lr / bias1)));
            }
        });
    }

    /// The moments as a checkpoint-format file (names `m/<variable>` and `v/<variable>`), tagged
    /// with the model config and the step they belong to.
    pub fn to_bytes(&self, cfg: &ModelConfig, meta: &Meta) -> Result<Vec<u8>, CheckpointError> {
        let named = self.moments.iter().flat_map(|(name, mo)| {
            [
                (format!("m/{name}"), mo.m.shallow_clone()),
                (format!("v/{name}"), mo.v.shallow_clone()),
            ]
        });
        checkpoint::encode(FORMAT, named, cfg, meta)
    }

    /// Restores moments written by [`Adam::to_bytes`] after checking format, checksum, config
    /// and every name and shape; on any difference nothing changes. Returns the stored meta.
    pub fn load_bytes(&mut self, bytes: &[u8], cfg: &ModelConfig) -> Result<Meta, CheckpointError> {
        let ck: Checkpoint = checkpoint::decode(FORMAT, bytes)?;
        let diff = ck.config.differences(cfg);
        if !diff.is_empty() {
            return Err(CheckpointError::Config(diff));
        }
        let expected: HashMap<String, Tensor> = self
            .moments
            .iter()
            .flat_map(|(name, mo)| {
                [
                    (format!("m/{name}"), mo.m.shallow_clone()),
                    (format!("v/{name}"), mo.v.shallow_clone()),
                ]
            })
            .collect();
        let problems = ck.tensor_differences(&expected);
        if !problems.is_empty() {
            return Err(CheckpointError::Tensors(problems));
        }
        for (name, mo) in &mut self.moments {
            mo.m = ck.tensors[&format!("m/{name}")].copy();
            mo.v = ck.tensors[&format!("v/{name}")].copy();
        }
        Ok(ck.meta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tch::nn::OptimizerConfig;
    use tch::{Device, Kind};

    fn params(seed: i64) -> VarStore {
        tch::manual_seed(seed);
        let vs = VarStore::new(Device::Cpu);
        let _ = vs.root().randn("w", &[3, 4], 0.0, 1.0);
        let _ = vs.root().randn("b", &[4], 0.0, 1.0);
        vs
    }

    fn loss(vs: &VarStore, x: &Tensor) -> Tensor {
        let v = vs.variables();
        (x.matmul(&v["w"]) + &v["b"])
            .tanh()
            .square()
            .sum(Kind::Float)
    }

    #[test]
    fn same_steps_as_libtorch_adam() {
        // One draw copied: tests in this binary reseed the global RNG in parallel.
        let ours_vs = params(3);
        let mut theirs_vs = params(3);
        theirs_vs.copy(&ours_vs).unwrap();
        let mut ours = Adam::new(&ours_vs, 0.01);
        let mut theirs = tch::nn::adam(0.9, 0.999, 0.0)
            .build(&theirs_vs, 0.01)
            .unwrap();
        for t in 1..=20 {
            let x = Tensor::randn([5, 3], (Kind::Float, Device::Cpu));
            ours.zero_grad(&ours_vs);
            loss(&ours_vs, &x).backward();
            ours.step(&ours_vs, t);
            theirs.zero_grad();
            loss(&theirs_vs, &x).backward();
            theirs.step();
        }
        let (a, b) = (ours_vs.variables(), theirs_vs.variables());
        for name in ["w", "b"] {
            let gap = (&a[name] - &b[name]).abs().max().double_value(&[]);
            assert!(gap < 1e-6, "{name} differs from libtorch's Adam by {gap}");
        }
        let moved = (&a["w"] - &params(3).variables()["w"]).abs().max();
        assert!(
            moved.double_value(&[]) > 0.05,
            "the steps moved the weights"
        );
    }
}
