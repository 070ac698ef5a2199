//! The trainer judges its own weights for control: every `probe_every_updates` it runs the
//! counterfactual probe (`mtanet_eval::probe`) in a private MuJoCo world of the stack's scene
//! and sends the score with the next weights; the predictor drives by active inference only with
//! weights whose probe passed.

use mtanet_control::AgentConfig;
use mtanet_eval::{ProbeConfig, ProbeReport};
use mtanet_scenes::SceneConfig;

pub struct Prober {
    pub scene: SceneConfig,
    pub agent: AgentConfig,
    pub cfg: ProbeConfig,
    pub every: u64,
}

impl Prober {
    pub fn due(&self, step: u64) -> bool {
        self.every > 0 && step % self.every == 0
    }

    pub fn run(&self, checkpoint: &[u8]) -> anyhow::Result<ProbeReport> {
        mtanet_eval::probe(&self.scene, checkpoint, &self.agent, &self.cfg)
    }
}
