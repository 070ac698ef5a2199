//! Records a drive as a dataset `.npz`: `images` float32 `[N,T,H,W]` in [0,1] and `actions`
//! float32 `[N,T,2]`, where `actions[:, t]` is the wheel command applied from frame t-1 to frame t
//! (what moved the world there; the same convention as the replay chunks). Sequences are consecutive, non-overlapping windows;
//! a partial window at the end is dropped. Written to a temp file and renamed, so a crash never
//! leaves a half-written dataset under the final name.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::Context;
use mtanet_scenes::{IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH};
use ndarray::{Array3, Array4};
use ndarray_npy::NpzWriter;

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
        let images = Array4::from_shape_vec(
            (n, t, IMAGE_HEIGHT, IMAGE_WIDTH),
            self.images[..n * t * IMAGE_PIXELS].to_vec(),
        )?;
        let actions = Array3::from_shape_vec((n, t, 2), self.actions[..n * t * 2].to_vec())?;
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let tmp = tempfile::NamedTempFile::new_in(dir)
            .with_context(|| format!("temp file in {}", dir.display()))?;
        {
            let mut npz = NpzWriter::new(BufWriter::new(File::create(tmp.path())?));
            npz.add_array("images", &images).context("writing images")?;
            npz.add_array("actions", &actions)
                .context("writing actions")?;
            npz.finish().context("finishing npz")?;
        }
        tmp.persist(path)
            .with_context(|| format!("renaming into {}", path.display()))?;
        Ok(())
    }
}
