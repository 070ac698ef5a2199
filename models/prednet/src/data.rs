//! Data sets: `images` float32 `[N, T, H, W]` in [0, 1] and `actions` float32 `[N, T, A]`, where
//! `actions[:, t]` moved the world from frame t-1 to t, stored as a numpy `.npz`.

use mtanet_summaries::files::NpzArray;
use ndarray::ArrayD;
use ndarray_npy::{NpzReader, ReadNpyError, ReadNpzError};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use std::fs::File;
use std::path::{Path, PathBuf};
use tch::{Kind, Tensor};

/// Why a data set could not be read, written or accepted.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The file could not be opened or created.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The file is not a readable zip/npz archive (truncated, corrupt, an unsupported compression).
    #[error("{path}: not a readable .npz archive: {source}")]
    Archive { path: PathBuf, source: ReadNpzError },
    /// A required array is absent.
    #[error("{path}: no array `{array}` (arrays present: {present:?})")]
    Missing {
        path: PathBuf,
        array: &'static str,
        present: Vec<String>,
    },
    /// An array is present but cannot be read as float32/float64.
    #[error("{path}: array `{array}` is not readable as float32: {detail}")]
    Dtype {
        path: PathBuf,
        array: &'static str,
        detail: String,
    },
    /// Array shapes are wrong or disagree with each other.
    #[error("{path}: {detail}")]
    Shape { path: PathBuf, detail: String },
    /// Values are NaN/inf, or images fall outside [0, 1].
    #[error("{path}: array `{array}` {detail}")]
    Values {
        path: PathBuf,
        array: &'static str,
        detail: String,
    },
    /// Writing the archive failed.
    #[error("{path}: cannot write npz: {detail}")]
    Write { path: PathBuf, detail: String },
}

/// A set of N equally long sequences, held as CPU float32 tensors.
#[derive(Debug)]
pub struct Dataset {
    /// `[N, T, H, W]` in [0, 1].
    pub images: Tensor,
    /// `[N, T, A]`.
    pub actions: Tensor,
}

const MEMORY: &str = "<in memory>";

impl Dataset {
    /// Validates shapes, kinds and values; `images` may also be `[N, T, 1, H, W]`.
    pub fn new(images: Tensor, actions: Tensor) -> Result<Self, DataError> {
        Self::checked(images, actions, Path::new(MEMORY))
    }

    fn checked(images: Tensor, actions: Tensor, path: &Path) -> Result<Self, DataError> {
        let shape = |detail: String| DataError::Shape {
            path: path.to_owned(),
            detail,
        };
        let (is, as_) = (images.size(), actions.size());
        let images = match is.as_slice() {
            [n, t, 1, h, w] => images.reshape([*n, *t, *h, *w]),
            [_, _, _, _] => images,
            _ => return Err(shape(format!("`images` must be [N, T, H, W], got {is:?}"))),
        };
        let is = images.size();
        if as_.len() != 3 || as_[..2] != is[..2] {
            return Err(shape(format!(
                "`actions` must be [N, T, A] with N, T of images {is:?}, got {as_:?}"
            )));
        }
        if is.iter().chain(&as_).any(|&d| d == 0) {
            return Err(shape(format!(
                "empty data set: images {is:?}, actions {as_:?}"
            )));
        }
        if is[1] < 2 {
            return Err(shape(format!(
                "sequences need at least 2 steps for next-frame prediction, got {}",
                is[1]
            )));
        }
        let images = images.to_kind(Kind::Float).contiguous();
        let actions = actions.to_kind(Kind::Float).contiguous();
        let values = |array, detail: String| DataError::Values {
            path: path.to_owned(),
            array,
            detail,
        };
        for (name, t) in [("images", &images), ("actions", &actions)] {
            let bad = t.isfinite().logical_not().sum(Kind::Int64).int64_value(&[]);
            if bad > 0 {
                return Err(values(name, format!("has {bad} NaN/inf values")));
            }
        }
        let (lo, hi) = (
            images.min().double_value(&[]),
            images.max().double_value(&[]),
        );
        if lo < 0.0 || hi > 1.0 {
            return Err(values(
                "images",
                format!("must lie in [0, 1], found [{lo}, {hi}] (uint8 frames need / 255)"),
            ));
        }
        Ok(Self { images, actions })
    }

    /// Reads `images` and `actions` (float32, or float64 converted) from a numpy `.npz`.
    pub fn load_npz(path: impl AsRef<Path>) -> Result<Self, DataError> {
        let path = path.as_ref();
        let file = File::open(path).map_err(|source| DataError::Io {
            path: path.to_owned(),
            source,
        })?;
        let mut npz = NpzReader::new(file).map_err(|source| DataError::Archive {
            path: path.to_owned(),
            source,
        })?;
        let names = npz.names().map_err(|source| DataError::Archive {
            path: path.to_owned(),
            source,
        })?;
        let images = read_array(&mut npz, &names, path, "images")?;
        let actions = read_array(&mut npz, &names, path, "actions")?;
        Self::checked(images, actions, path)
    }

    /// Writes `images` and `actions` as float32 arrays, uncompressed (numpy `np.savez` layout),
    /// atomically (the same writer as the simulator's recordings).
    pub fn save_npz(&self, path: impl AsRef<Path>) -> Result<(), DataError> {
        let path = path.as_ref();
        let flat = |t: &Tensor| {
            Vec::<f32>::try_from(t.flatten(0, -1)).map_err(|e| DataError::Write {
                path: path.to_owned(),
                detail: e.to_string(),
            })
        };
        let shape = |t: &Tensor| t.size().iter().map(|&d| d as usize).collect();
        let (images, actions) = (flat(&self.images)?, flat(&self.actions)?);
        mtanet_summaries::files::write_npz(
            path,
            &[
                NpzArray {
                    name: "images",
                    shape: shape(&self.images),
                    data: &images,
                },
                NpzArray {
                    name: "actions",
                    shape: shape(&self.actions),
                    data: &actions,
                },
            ],
        )
        .map_err(|e| DataError::Write {
            path: path.to_owned(),
            detail: e.to_string(),
        })
    }

    /// The sequences of all `sets` in order; they must agree on T, H, W and A.
    pub fn concat(sets: &[Dataset]) -> Result<Dataset, DataError> {
        let shape = |detail: String| DataError::Shape {
            path: PathBuf::from(MEMORY),
            detail,
        };
        let first = sets
            .first()
            .ok_or_else(|| shape("nothing to concatenate".into()))?;
        let key = |d: &Dataset| (d.steps(), d.image_size(), d.action_dim());
        if let Some(d) = sets.iter().find(|d| key(d) != key(first)) {
            return Err(shape(format!(
                "cannot concatenate (T, (H, W), A) {:?} with {:?}",
                key(first),
                key(d)
            )));
        }
        let images: Vec<&Tensor> = sets.iter().map(|d| &d.images).collect();
        let actions: Vec<&Tensor> = sets.iter().map(|d| &d.actions).collect();
        Ok(Dataset {
            images: Tensor::cat(&images, 0),
            actions: Tensor::cat(&actions, 0),
        })
    }

    /// Per action component (mean, std) over all steps, for `ModelConfig::action_offset` /
    /// `action_scale`; a constant component gets scale 1.
    pub fn action_normalisation(&self) -> (Vec<f64>, Vec<f64>) {
        let flat = self
            .actions
            .reshape([-1, self.action_dim()])
            .to_kind(Kind::Double);
        let dim = [0i64];
        let mean = Vec::<f64>::try_from(flat.mean_dim(dim.as_slice(), false, Kind::Double));
        let std = Vec::<f64>::try_from(flat.std_dim(dim.as_slice(), false, false));
        let (mean, std) = (mean.unwrap_or_default(), std.unwrap_or_default());
        (
            mean,
            std.into_iter()
                .map(|s| if s > 1e-6 { s } else { 1.0 })
                .collect(),
        )
    }

    /// Number of sequences N.
    pub fn len(&self) -> i64 {
        self.images.size()[0]
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Steps per sequence T.
    pub fn steps(&self) -> i64 {
        self.images.size()[1]
    }

    /// (H, W).
    pub fn image_size(&self) -> (i64, i64) {
        let s = self.images.size();
        (s[2], s[3])
    }

    pub fn action_dim(&self) -> i64 {
        self.actions.size()[2]
    }

    /// The sequences at `index` (a list of sequence numbers).
    pub fn select(&self, index: &[i64]) -> Dataset {
        let idx = Tensor::from_slice(index);
        Dataset {
            images: self.images.index_select(0, &idx),
            actions: self.actions.index_select(0, &idx),
        }
    }

    /// Seeded split into (train, held-out) with `ceil(fraction * N)` held-out sequences (at least
    /// one, and at least one left for training when N >= 2).
    pub fn split(&self, fraction: f64, seed: u64) -> (Dataset, Dataset) {
        let n = self.len();
        let mut order: Vec<i64> = (0..n).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        let held = ((fraction * n as f64).ceil() as i64).clamp(1, (n - 1).max(1));
        let (eval, train) = order.split_at(held as usize);
        (self.select(train), self.select(eval))
    }

    /// The same images with each sequence's actions taken from another sequence (a seeded
    /// derangement: nobody keeps their own). With a single sequence the actions are reversed in
    /// time instead. Used to prove that the model uses the action.
    pub fn shuffled_actions(&self, seed: u64) -> Tensor {
        let n = self.len();
        if n < 2 {
            return self.actions.flip([1]);
        }
        let mut order: Vec<i64> = (0..n).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        // Cycle along the shuffled order: sequence order[i] gets the actions of order[i + 1].
        let mut source = vec![0i64; n as usize];
        for i in 0..n as usize {
            source[order[i] as usize] = order[(i + 1) % n as usize];
        }
        self.actions.index_select(0, &Tensor::from_slice(&source))
    }
}

fn read_array(
    npz: &mut NpzReader<File>,
    names: &[String],
    path: &Path,
    array: &'static str,
) -> Result<Tensor, DataError> {
    if !names.iter().any(|n| n == array) {
        return Err(DataError::Missing {
            path: path.to_owned(),
            array,
            present: names.to_vec(),
        });
    }
    let dtype = |detail: String| DataError::Dtype {
        path: path.to_owned(),
        array,
        detail,
    };
    let result: Result<ArrayD<f32>, ReadNpzError> = npz.by_name(array);
    let data = match result {
        Ok(a) => a,
        Err(ReadNpzError::Npy(ReadNpyError::WrongDescriptor(d))) => {
            // float64 writers (numpy's default) are common: accept and narrow.
            let a: ArrayD<f64> = npz
                .by_name(array)
                .map_err(|_| dtype(format!("descriptor {d}")))?;
            a.mapv(|v| v as f32)
        }
        Err(source @ ReadNpzError::Zip(_)) => {
            return Err(DataError::Archive {
                path: path.to_owned(),
                source,
            });
        }
        Err(e) => return Err(dtype(e.to_string())),
    };
    let dims: Vec<i64> = data.shape().iter().map(|&d| d as i64).collect();
    let data = data.as_standard_layout();
    let slice = data
        .as_slice()
        .ok_or_else(|| dtype("not contiguous after relayout".into()))?;
    Ok(Tensor::from_slice(slice).reshape(dims))
}

#[cfg(test)]
mod tests;
