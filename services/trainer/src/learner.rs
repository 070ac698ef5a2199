//! Online learning: batches sampled from the replay buffer, one Adam update at a time, weights
//! published to the predictor every few updates and kept on disk for restarts.

use std::path::{Path, PathBuf};

use anyhow::Context;
use mtanet_ipc::{ACTION_DIM, IMAGE_HEIGHT, IMAGE_WIDTH, WeightsHeader};
use mtanet_models::Trainer;
use mtanet_models::checkpoint::{CheckpointError, SCHEMA_VERSION};
use mtanet_models::train::UpdateStats;
use mtanet_models::train::optimizer_path;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use tch::Tensor;

use crate::config::TrainerConfig;
use crate::probe::Prober;
use crate::replay::{Batch, ReplayBuffer};

/// One training update, and the weights to publish after it when a publication was due.
pub struct Update {
    pub stats: UpdateStats,
    pub publish: Option<Publication>,
}

/// Weights for the predictor: a whole checkpoint's bytes and the header that goes with them.
pub struct Publication {
    pub header: WeightsHeader,
    pub bytes: Vec<u8>,
}

/// The newest checkpoint in `checkpoint_dir`, and the one before it.
pub const LATEST: &str = "latest.safetensors";
pub const PREVIOUS: &str = "previous.safetensors";

fn rename(from: &Path, to: &Path) -> Result<(), CheckpointError> {
    std::fs::rename(from, to).map_err(|source| CheckpointError::Io {
        path: from.to_owned(),
        source,
    })
}

/// Resumes from the newest readable checkpoint in `dir` (latest, else previous); returns its
/// step (0: a fresh start). A damaged file is refused with its reason and the older one tried;
/// one written for another network is an error: the operator changed `[trainer.model]` and must
/// decide, rather than lose the learning to a silent fresh start.
fn resume(trainer: &mut Trainer, dir: &Path) -> anyhow::Result<u64> {
    let mut refused = Vec::new();
    for name in [LATEST, PREVIOUS] {
        let path = dir.join(name);
        if !path.exists() {
            continue;
        }
        match trainer.resume(&path) {
            Ok(meta) => {
                if refused.is_empty() {
                    tracing::info!(path = %path.display(), step = meta.step, "resumed training");
                } else {
                    tracing::warn!(path = %path.display(), step = meta.step, "resumed training from the previous checkpoint");
                }
                return Ok(meta.step);
            }
            Err(e @ CheckpointError::Config(_)) => {
                return Err(e).with_context(|| format!("resuming from {}", path.display()));
            }
            Err(e) => {
                tracing::error!(path = %path.display(), "refusing a damaged checkpoint: {e}");
                refused.push(path.display().to_string());
            }
        }
    }
    if refused.is_empty() {
        tracing::info!(dir = %dir.display(), "no checkpoint yet: training starts fresh");
    } else {
        tracing::warn!(refused = ?refused, "no usable checkpoint: training starts fresh");
    }
    Ok(0)
}

pub struct Learner {
    trainer: Trainer,
    rng: ChaCha8Rng,
    min_sequences: usize,
    sequence_steps: usize,
    mirror: bool,
    publish_every: u64,
    /// The counterfactual probe, run every so many updates (none: never).
    prober: Option<Prober>,
    checkpoint: Option<PathBuf>,
    version: u64,
    last_loss: Option<f64>,
    /// Training step of the checkpoint on disk, so a stop saves only what is new.
    saved_step: u64,
    /// Training step of the checkpoint resumed from (0: a fresh start).
    resumed_from: u64,
    pub refused: u64,
}

impl Learner {
    /// Builds the model; resumes from `checkpoint_dir/latest.safetensors` when present.
    pub fn new(cfg: &TrainerConfig) -> anyhow::Result<Self> {
        cfg.model
            .check_wire((IMAGE_HEIGHT, IMAGE_WIDTH), ACTION_DIM)
            .context("[trainer.model]")?;
        let mut trainer = Trainer::f_new(&cfg.model, &cfg.train)
            .context("building the model from [trainer.model]")?;
        if let Some(dir) = &cfg.checkpoint_dir {
            // Fail at start, not after the first hour of training.
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating trainer.checkpoint_dir {}", dir.display()))?;
        }
        let checkpoint = cfg.checkpoint_dir.as_ref().map(|d| d.join(LATEST));
        let saved_step = match &cfg.checkpoint_dir {
            Some(dir) => resume(&mut trainer, dir)?,
            None => 0,
        };
        Ok(Self {
            trainer,
            rng: ChaCha8Rng::seed_from_u64(cfg.train.seed),
            min_sequences: cfg.min_sequences.max(1),
            sequence_steps: cfg.sequence_steps.max(2),
            mirror: cfg.mirror,
            publish_every: cfg.publish_every_updates.max(1),
            prober: None,
            checkpoint,
            version: 0,
            last_loss: None,
            saved_step,
            resumed_from: saved_step,
            refused: 0,
        })
    }

    /// The latest probe: (training step, rank correlation).
    pub fn probe(&self) -> Option<(u64, f64)> {
        self.trainer.probe
    }

    pub fn updates(&self) -> u64 {
        self.trainer.step()
    }

    pub fn last_loss(&self) -> Option<f64> {
        self.last_loss
    }

    /// Whether the update that reaches training step `step` publishes its weights.
    pub fn publishes_at(&self, step: u64) -> bool {
        step % self.publish_every == 0 || self.prober.as_ref().is_some_and(|p| p.due(step))
    }

    /// Training step of the checkpoint resumed from (0: a fresh start).
    pub fn resumed_from(&self) -> u64 {
        self.resumed_from
    }

    pub fn published(&self) -> u64 {
        self.version
    }

    /// Runs the counterfactual probe with `prober` every its interval of updates.
    pub fn set_prober(&mut self, prober: Prober) {
        self.prober = Some(prober);
    }

    pub fn ready(&self, buffer: &ReplayBuffer) -> bool {
        buffer.len() >= self.min_sequences
    }

    /// Control steps per model step of the network trained.
    pub fn frame_skip(&self) -> usize {
        self.trainer.cfg.frame_skip.max(1) as usize
    }

    /// One update on a random batch of windows; probes when due, and when a publication is due
    /// returns it with the update (the service sends it). A refused (non-finite) update is
    /// logged and counted, the weights stay as they were. `None` also when the buffer holds no
    /// run of driving long enough for a window yet. `upto`: draw only from the chunks received
    /// before this one (lockstep learning's horizon).
    pub fn train_once(
        &mut self,
        buffer: &ReplayBuffer,
        upto: Option<u64>,
    ) -> anyhow::Result<Option<Update>> {
        let b = self.trainer.train_cfg.batch_size.max(1) as usize;
        let shape = (b, self.sequence_steps, self.frame_skip());
        let Some(batch) = buffer.sample(&mut self.rng, shape, self.mirror, upto) else {
            return Ok(None);
        };
        let (images, actions) = to_tensors(&batch);
        match self.trainer.update(&images, &actions) {
            Ok(stats) => {
                self.last_loss = Some(stats.loss);
                let probe_due = self.prober.as_ref().is_some_and(|p| p.due(stats.step));
                if probe_due {
                    self.run_probe()?;
                }
                let publish = if probe_due || self.publishes_at(stats.step) {
                    Some(self.publication()?)
                } else {
                    None
                };
                Ok(Some(Update { stats, publish }))
            }
            Err(
                e @ (mtanet_models::train::TrainError::NonFiniteLoss { .. }
                | mtanet_models::train::TrainError::NonFiniteGradient { .. }),
            ) => {
                self.refused += 1;
                tracing::warn!("{e}");
                Ok(None)
            }
            Err(e) => Err(e).context("training update"),
        }
    }

    /// The counterfactual probe of the current weights (a few seconds of simulation).
    fn run_probe(&mut self) -> anyhow::Result<()> {
        let Some(prober) = self.prober.as_ref() else {
            return Ok(());
        };
        let bytes = self
            .trainer
            .checkpoint_bytes(self.last_loss)
            .context("serialising the checkpoint for the probe")?;
        let t0 = std::time::Instant::now();
        match prober.run(&bytes) {
            Ok(r) => {
                tracing::info!(
                    step = self.trainer.step(),
                    rank_correlation = r.rank_correlation,
                    top2 = r.top2_agreement,
                    states = r.states,
                    seconds = t0.elapsed().as_secs_f64(),
                    "counterfactual probe"
                );
                self.trainer.probe = Some((self.trainer.step(), r.rank_correlation));
            }
            // The probe judges the model; failing to run it must not stop the learning.
            Err(e) => tracing::error!("the counterfactual probe failed: {e:#}"),
        }
        Ok(())
    }

    /// The current weights as the next version for the predictor, kept on disk first (when
    /// configured) so that the disk never holds older weights than the predictor runs.
    pub fn publication(&mut self) -> anyhow::Result<Publication> {
        let bytes = self
            .trainer
            .checkpoint_bytes(self.last_loss)
            .context("serialising the checkpoint")?;
        self.version += 1;
        let header = WeightsHeader {
            version: self.version,
            train_step: self.trainer.step(),
            loss: self.last_loss.unwrap_or(f64::NAN) as f32,
            schema: SCHEMA_VERSION,
            probe_step: self.trainer.probe.map_or(0, |p| p.0),
            probe: self.trainer.probe.map_or(f32::NAN, |p| p.1 as f32),
            ..Default::default()
        };
        // A full disk must not end the learning in memory: say so and keep training.
        if let Err(e) = self.save(Some(&bytes)) {
            tracing::error!(path = ?self.checkpoint, "could not save the checkpoint: {e}");
        }
        Ok(Publication { header, bytes })
    }

    /// On a clean stop, keeps the updates made since the last publish (up to
    /// `publish_every_updates` of them) on disk.
    pub fn save_on_stop(&mut self) -> anyhow::Result<()> {
        if self.checkpoint.is_none() || self.trainer.step() == self.saved_step {
            return Ok(());
        }
        self.save(None).context("saving the checkpoint at stop")?;
        tracing::info!(path = ?self.checkpoint, step = self.saved_step, "checkpoint saved at stop");
        Ok(())
    }

    /// Writes the checkpoint (and Adam's moments) when `checkpoint_dir` is set, keeping the one
    /// before as `previous.*`: the old latest is renamed (atomic) before the new one is written
    /// (temp file + rename), so a failed write (disk full) leaves the last good one intact.
    /// `bytes`: the serialisation a publication already made (one per publication), else a
    /// fresh one.
    fn save(&mut self, bytes: Option<&[u8]>) -> Result<(), CheckpointError> {
        if let Some(path) = &self.checkpoint {
            let previous = path.with_file_name(PREVIOUS);
            if path.exists() {
                rename(path, &previous)?;
                let opt = optimizer_path(path);
                if opt.exists() {
                    rename(&opt, &optimizer_path(&previous))?;
                }
            }
            match bytes {
                Some(b) => self
                    .trainer
                    .save_checkpoint_bytes(path, b, self.last_loss)?,
                None => self.trainer.save_checkpoint(path, self.last_loss)?,
            }
            self.saved_step = self.trainer.step();
        }
        Ok(())
    }

    /// True when resuming loaded weights worth sending before the first new update.
    pub fn has_trained_weights(&self) -> bool {
        self.trainer.step() > 0
    }
}

/// `[B, T, H, W]` images and `[B, T, A]` actions.
fn to_tensors(b: &Batch) -> (Tensor, Tensor) {
    let (n, t) = (b.batch as i64, b.steps as i64);
    (
        Tensor::from_slice(&b.images).view([n, t, IMAGE_HEIGHT as i64, IMAGE_WIDTH as i64]),
        Tensor::from_slice(&b.actions).view([n, t, ACTION_DIM as i64]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_models::ModelConfig;

    fn cfg(dir: &Path) -> TrainerConfig {
        TrainerConfig {
            checkpoint_dir: Some(dir.to_owned()),
            model: ModelConfig {
                channels: vec![4, 4, 4],
                a_channels: vec![1, 4, 4],
                ..TrainerConfig::default().model
            },
            ..TrainerConfig::default()
        }
    }

    fn saved_at(l: &mut Learner, step: u64) {
        l.trainer.set_step(step);
        l.save(None).unwrap();
    }

    fn truncate(p: &Path) {
        let b = std::fs::read(p).unwrap();
        std::fs::write(p, &b[..b.len() / 2]).unwrap();
    }

    #[test]
    fn a_publication_keeps_on_disk_the_bytes_it_sends() {
        let dir = tempfile::tempdir().unwrap();
        let mut l = Learner::new(&cfg(dir.path())).unwrap();
        l.trainer.set_step(7);
        let p = l.publication().unwrap();
        assert_eq!(std::fs::read(dir.path().join(LATEST)).unwrap(), p.bytes);
        // The same as serialising afresh: one serialisation serves both.
        assert_eq!(p.bytes, l.trainer.checkpoint_bytes(l.last_loss).unwrap());
    }

    #[test]
    fn keeps_two_checkpoints_and_falls_back_to_the_older_when_the_newer_is_damaged() {
        let dir = tempfile::tempdir().unwrap();
        let c = cfg(dir.path());
        let mut l = Learner::new(&c).unwrap();
        assert_eq!(l.updates(), 0, "nothing on disk: a fresh start");
        saved_at(&mut l, 10);
        saved_at(&mut l, 20);
        assert!(dir.path().join(PREVIOUS).exists() && dir.path().join(LATEST).exists());
        assert_eq!(
            Learner::new(&c).unwrap().updates(),
            20,
            "the newest when it is good"
        );
        truncate(&dir.path().join(LATEST));
        assert_eq!(
            Learner::new(&c).unwrap().updates(),
            10,
            "the previous when the newest is damaged"
        );
        truncate(&dir.path().join(PREVIOUS));
        assert_eq!(
            Learner::new(&c).unwrap().updates(),
            0,
            "neither: a fresh start, not a crash"
        );
        // A checkpoint of another network is the operator's call, not a silent fresh start.
        let mut other = cfg(dir.path());
        other.model.channels = vec![8, 4, 4];
        let mut l = Learner::new(&c).unwrap();
        saved_at(&mut l, 30);
        let e = Learner::new(&other)
            .err()
            .expect("a config mismatch is an error");
        assert!(format!("{e:#}").contains("configuration differs"), "{e:#}");
    }

    #[test]
    fn a_network_off_the_wire_contract_is_refused_at_start() {
        let dir = tempfile::tempdir().unwrap();
        let mut c = cfg(dir.path());
        c.model.action_dim = 3;
        let e = Learner::new(&c)
            .err()
            .expect("3 action values, commands have 2");
        assert!(format!("{e:#}").contains("action values"), "{e:#}");
    }

    #[test]
    fn a_failed_save_leaves_the_last_good_checkpoint_intact() {
        let dir = tempfile::tempdir().unwrap();
        let c = cfg(dir.path());
        let mut l = Learner::new(&c).unwrap();
        saved_at(&mut l, 10);
        // The disk refuses the next write: a directory sits where the temporary file would go.
        let blocker = dir
            .path()
            .join(format!(".{LATEST}.tmp{}", std::process::id()));
        std::fs::create_dir(&blocker).unwrap();
        l.trainer.set_step(20);
        assert!(
            l.save(None).is_err(),
            "the write must fail for the test to mean anything"
        );
        assert_eq!(
            Learner::new(&c).unwrap().updates(),
            10,
            "the step-10 checkpoint is still there"
        );
        std::fs::remove_dir(&blocker).unwrap();
        saved_at(&mut l, 30);
        assert_eq!(
            Learner::new(&c).unwrap().updates(),
            30,
            "saving works again"
        );
    }
}
