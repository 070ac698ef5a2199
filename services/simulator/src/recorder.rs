//! Records a drive as a dataset `.npz`: `images` float32 `[N,T,H,W]` in [0,1] and `actions`
//! float32 `[N,T,2]`, where `actions[:, t]` is the wheel command applied from frame t-1 to frame t
//! (what moved the world there; the same convention as the replay chunks). Sequences are consecutive, non-overlapping windows;
//! a partial window at the end is dropped. Written atomically (`mtanet_summaries::files`): a crash never
//! leaves a half-written dataset under the final name.

use std::path::Path;

use mtanet_scenes::{IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH};
use mtanet_summaries::files::NpzArray;

pub struct Recorder {
    seq_len: usize,
    images: Vec<f32>,
    actions: Vec<f32>,
    steps: usize,
}

impl Recorder {
    pub fn new(seq_len: usize) -> Self {
        assert!(seq_len > 0, "sequence length must be positive");
        Self {
            seq_len,
            images: Vec::new(),
            actions: Vec::new(),
            steps: 0,
        }
    }

    pub fn push(&mut self, image: &[f32; IMAGE_PIXELS], action: [f32; 2]) {
        self.images.extend_from_slice(image);
        self.actions.extend_from_slice(&action);
        self.steps += 1;
    }

    /// Complete sequences so far.
    pub fn sequences(&self) -> usize {
        self.steps / self.seq_len
    }

    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let (n, t) = (self.sequences(), self.seq_len);
        anyhow::ensure!(
            n > 0,
            "nothing to record: {} steps is less than one sequence of {t}",
            self.steps
        );
        let array = |name, shape, data| NpzArray { name, shape, data };
        mtanet_summaries::files::write_npz(
            path,
            &[
                array(
                    "images",
                    vec![n, t, IMAGE_HEIGHT, IMAGE_WIDTH],
                    &self.images[..n * t * IMAGE_PIXELS],
                ),
                array("actions", vec![n, t, 2], &self.actions[..n * t * 2]),
            ],
        )?;
        Ok(())
    }
}
