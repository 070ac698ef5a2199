//! Checkpoints: one safetensors file holding the weights, the model configuration and metadata
//! (header `__metadata__["mtanet"]`: a JSON object with format, schema version, config, meta and
//! checksum).
//!
//! The bytes form ([`to_bytes`]) is exactly the file content: it is what the trainer hands the
//! predictor over shared memory. Loading validates everything before touching a variable, so a
//! bad checkpoint never leaves a half-loaded model.

use crate::config::ModelConfig;
use crate::model::MtaPredNet;
use safetensors::tensor::TensorView;
use safetensors::{Dtype, SafeTensors};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use tch::{Device, Kind, Tensor, nn::VarStore};

/// Bumped whenever the file layout or the meaning of a variable changes.
/// 2: a layer's generative units stored as one block (`layer{l}.units.{wx,wh,bias}`); 1 had one
/// convolution per unit (`layer{l}.gu{d}.conv.{weight,bias}`) and is converted on reading.
pub const SCHEMA_VERSION: u32 = 2;
const FORMAT: &str = "mtanet-checkpoint";
/// The `__metadata__` entry holding format, schema version, config, meta and checksum.
const METADATA_KEY: &str = "mtanet";

/// Training metadata stored with the weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    pub schema_version: u32,
    /// Accepted training updates when saved.
    pub step: u64,
    /// Last training loss (JSON has no NaN, hence the option).
    pub loss: Option<f64>,
    /// Seconds since the Unix epoch when saved.
    pub unix_time: u64,
    /// The latest counterfactual probe of the training run (rank correlation) and the step it
    /// was measured at, so a model started from this file alone can be judged for control.
    #[serde(default)]
    pub probe: Option<f64>,
    #[serde(default)]
    pub probe_step: Option<u64>,
}

impl Meta {
    pub fn new(step: u64, loss: Option<f64>) -> Self {
        let unix_time = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        Self {
            schema_version: SCHEMA_VERSION,
            step,
            loss: loss.filter(|l| l.is_finite()),
            unix_time,
            probe: None,
            probe_step: None,
        }
    }

    /// With the latest probe `(step, rank correlation)`.
    pub fn with_probe(mut self, probe: Option<(u64, f64)>) -> Self {
        self.probe_step = probe.map(|p| p.0);
        self.probe = probe.map(|p| p.1).filter(|p| p.is_finite());
        self
    }
}

/// Why a checkpoint could not be written, read or applied.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// Reading, writing or renaming the file failed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Writing the file failed (it names the file).
    #[error(transparent)]
    Write(#[from] mtanet_summaries::files::FileError),
    /// The bytes are not a complete safetensors file (truncated, or the header is damaged).
    #[error("not a readable checkpoint (truncated or corrupt): {0}")]
    Corrupt(#[from] safetensors::SafeTensorError),
    /// A safetensors file, but not one of ours, or its metadata does not parse.
    #[error("not an mtanet checkpoint: {0}")]
    NotCheckpoint(String),
    /// Written by a different schema version.
    #[error("checkpoint schema version {found}, this build reads {expected}")]
    Schema { found: u32, expected: u32 },
    /// The weights do not hash to the value stored at save time (bit rot, partial overwrite).
    #[error("checksum mismatch: stored {stored}, computed {computed}: the weights are corrupt")]
    Checksum { stored: String, computed: String },
    /// The checkpoint's model configuration is not the expected one.
    #[error("configuration differs (checkpoint != expected): {}", .0.join("; "))]
    Config(Vec<String>),
    /// Names, shapes or dtypes differ between the checkpoint and the variables.
    #[error("tensors differ from the model's variables: {}", .0.join("; "))]
    Tensors(Vec<String>),
    /// A variable has a kind safetensors cannot store or we do not load.
    #[error("variable `{name}` has unsupported kind {kind}")]
    Kind { name: String, kind: String },
    /// A tensor holds NaN or infinity: such weights would plan with NaN and must never drive.
    #[error("tensor `{name}` holds {count} non-finite values (NaN or inf): refused")]
    NonFinite { name: String, count: i64 },
    /// Any of the above, in a file it names.
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        source: Box<CheckpointError>,
    },
}

/// A decoded checkpoint: configuration, metadata and named CPU tensors.
#[derive(Debug)]
pub struct Checkpoint {
    pub config: ModelConfig,
    pub meta: Meta,
    pub tensors: BTreeMap<String, Tensor>,
}

fn dtype_of(name: &str, kind: Kind) -> Result<Dtype, CheckpointError> {
    match kind {
        Kind::Float => Ok(Dtype::F32),
        Kind::Double => Ok(Dtype::F64),
        k => Err(CheckpointError::Kind {
            name: name.into(),
            kind: format!("{k:?}"),
        }),
    }
}

fn kind_of(name: &str, dtype: Dtype) -> Result<Kind, CheckpointError> {
    match dtype {
        Dtype::F32 => Ok(Kind::Float),
        Dtype::F64 => Ok(Kind::Double),
        d => Err(CheckpointError::Kind {
            name: name.into(),
            kind: format!("{d:?}"),
        }),
    }
}

/// FNV-1a 64 over names, dtypes, shapes and data in name order: cheap (~1 ms per MB) and enough
/// to catch damaged bytes, which the safetensors header alone cannot.
fn checksum<'a>(items: impl Iterator<Item = (&'a str, Dtype, &'a [usize], &'a [u8])>) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h = (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for (name, dtype, shape, data) in items {
        eat(name.as_bytes());
        eat(format!("{dtype:?}{shape:?}").as_bytes());
        eat(data);
    }
    format!("fnv1a64:{h:016x}")
}

/// The checkpoint as bytes (identical to the file [`save`] writes).
pub fn to_bytes(vs: &VarStore, cfg: &ModelConfig, meta: &Meta) -> Result<Vec<u8>, CheckpointError> {
    encode(FORMAT, vs.variables(), cfg, meta)
}

/// Named tensors with the header of `format` (weights: [`FORMAT`]; Adam moments: the
/// optimiser's format), as safetensors bytes.
pub(crate) fn encode(
    format: &str,
    tensors: impl IntoIterator<Item = (String, Tensor)>,
    cfg: &ModelConfig,
    meta: &Meta,
) -> Result<Vec<u8>, CheckpointError> {
    let mut raw: BTreeMap<String, (Dtype, Vec<usize>, Vec<u8>)> = BTreeMap::new();
    for (name, t) in tensors {
        let dtype = dtype_of(&name, t.kind())?;
        let t = t.to_device(Device::Cpu).contiguous();
        let numel = t.numel();
        let mut data = vec![0u8; numel * t.kind().elt_size_in_bytes()];
        t.f_copy_data_u8(&mut data, numel)
            .map_err(|e| CheckpointError::Kind {
                name: name.clone(),
                kind: e.to_string(),
            })?;
        let shape = t.size().iter().map(|&d| d as usize).collect();
        raw.insert(name, (dtype, shape, data));
    }
    let sum = checksum(
        raw.iter()
            .map(|(n, (d, s, b))| (n.as_str(), *d, s.as_slice(), b.as_slice())),
    );
    // One metadata entry holding a JSON object: safetensors keeps `__metadata__` in a HashMap,
    // whose order would differ between calls; one key makes the bytes deterministic.
    let header = serde_json::json!({
        "format": format,
        "schema_version": SCHEMA_VERSION,
        "config": cfg,
        "meta": meta,
        "checksum": sum,
    });
    let info = HashMap::from([(METADATA_KEY.to_string(), header.to_string())]);
    let views = raw
        .iter()
        .map(|(n, (d, s, b))| Ok((n.as_str(), TensorView::new(*d, s.clone(), b)?)))
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
    Ok(safetensors::serialize(views, Some(info))?)
}

/// Writes the checkpoint atomically: a temporary file in the same directory, fsync, rename.
/// Readers see the old file or the new one, never a partial one.
pub fn save(
    path: impl AsRef<Path>,
    vs: &VarStore,
    cfg: &ModelConfig,
    meta: &Meta,
) -> Result<(), CheckpointError> {
    Ok(mtanet_summaries::files::write_bytes(
        path.as_ref(),
        &to_bytes(vs, cfg, meta)?,
    )?)
}

/// Decodes and verifies (format, schema, checksum) a checkpoint held in memory.
pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, CheckpointError> {
    decode(FORMAT, bytes)
}

/// [`from_bytes`] for a file of `format`.
pub(crate) fn decode(format: &str, bytes: &[u8]) -> Result<Checkpoint, CheckpointError> {
    let st = SafeTensors::deserialize(bytes)?;
    let (_, header) = SafeTensors::read_metadata(bytes)?;
    let not_ours = |why: String| CheckpointError::NotCheckpoint(why);
    let text = header
        .metadata()
        .as_ref()
        .and_then(|m| m.get(METADATA_KEY))
        .ok_or_else(|| {
            not_ours(format!(
                "no `{METADATA_KEY}` entry in the safetensors metadata"
            ))
        })?;
    let info: serde_json::Value =
        serde_json::from_str(text).map_err(|e| not_ours(format!("metadata JSON: {e}")))?;
    if info["format"] != format {
        return Err(not_ours(format!("format {}", info["format"])));
    }
    let found = info["schema_version"]
        .as_u64()
        .ok_or_else(|| not_ours(format!("schema_version {}", info["schema_version"])))?;
    if found != u64::from(SCHEMA_VERSION) && found != 1 {
        return Err(CheckpointError::Schema {
            found: found as u32,
            expected: SCHEMA_VERSION,
        });
    }
    let config: ModelConfig = field(&info, "config")?;
    let meta: Meta = field(&info, "meta")?;
    let stored: String = field(&info, "checksum")?;
    let mut views: Vec<(String, TensorView)> = st.tensors();
    views.sort_by(|a, b| a.0.cmp(&b.0));
    let computed = checksum(
        views
            .iter()
            .map(|(n, v)| (n.as_str(), v.dtype(), v.shape(), v.data())),
    );
    if stored != computed {
        return Err(CheckpointError::Checksum { stored, computed });
    }
    let mut tensors = BTreeMap::new();
    for (name, v) in views {
        let kind = kind_of(&name, v.dtype())?;
        let size: Vec<i64> = v.shape().iter().map(|&d| d as i64).collect();
        let t =
            Tensor::f_from_data_size(v.data(), &size, kind).map_err(|e| CheckpointError::Kind {
                name: name.clone(),
                kind: e.to_string(),
            })?;
        let count = t.isfinite().logical_not().sum(Kind::Int64).int64_value(&[]);
        if count > 0 {
            return Err(CheckpointError::NonFinite { name, count });
        }
        tensors.insert(name, t);
    }
    if found == 1 {
        tensors = crate::checkpoint_v1::convert(tensors)?;
        tracing::info!(
            format,
            "read a schema-1 file (one convolution per generative unit) and converted it to schema 2 (one per layer); saving writes schema 2"
        );
    }
    Ok(Checkpoint {
        config,
        meta,
        tensors,
    })
}

fn field<T: serde::de::DeserializeOwned>(
    info: &serde_json::Value,
    key: &str,
) -> Result<T, CheckpointError> {
    serde_json::from_value(info[key].clone())
        .map_err(|e| CheckpointError::NotCheckpoint(format!("{key}: {e}")))
}

/// Reads and verifies a checkpoint file.
pub fn load(path: impl AsRef<Path>) -> Result<Checkpoint, CheckpointError> {
    read(path).map(|(_, ck)| ck)
}

/// Reads and verifies a checkpoint file; its bytes too, for what takes bytes (an imagination,
/// the probe). Every error names the file.
pub fn read(path: impl AsRef<Path>) -> Result<(Vec<u8>, Checkpoint), CheckpointError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io {
        path: path.to_owned(),
        source,
    })?;
    let ck = from_bytes(&bytes).map_err(|e| CheckpointError::InFile {
        path: path.to_owned(),
        source: Box::new(e),
    })?;
    Ok((bytes, ck))
}

/// Loads a checkpoint file into `vs`, whose model must have been built with `expected`.
pub fn load_into(
    path: impl AsRef<Path>,
    vs: &mut VarStore,
    expected: &ModelConfig,
) -> Result<Meta, CheckpointError> {
    let ck = load(path)?;
    ck.apply(vs, expected)?;
    Ok(ck.meta)
}

/// [`load_into`] from bytes.
pub fn load_bytes_into(
    bytes: &[u8],
    vs: &mut VarStore,
    expected: &ModelConfig,
) -> Result<Meta, CheckpointError> {
    let ck = from_bytes(bytes)?;
    ck.apply(vs, expected)?;
    Ok(ck.meta)
}

impl Checkpoint {
    /// Copies the weights into `vs` after checking the config and every name, shape and dtype;
    /// on any difference nothing is copied.
    pub fn apply(&self, vs: &mut VarStore, expected: &ModelConfig) -> Result<(), CheckpointError> {
        let diff = self.config.differences(expected);
        if !diff.is_empty() {
            return Err(CheckpointError::Config(diff));
        }
        let vars = vs.variables();
        let problems = self.tensor_differences(&vars);
        if !problems.is_empty() {
            return Err(CheckpointError::Tensors(problems));
        }
        tch::no_grad(|| {
            for (name, var) in &vars {
                let mut var = var.shallow_clone();
                var.f_copy_(&self.tensors[name])
                    .map_err(|e| CheckpointError::Tensors(vec![format!("`{name}`: {e}")]))?;
            }
            Ok(())
        })
    }

    /// Missing, unexpected, misshapen or mistyped tensors against `vars`, sorted; empty if none.
    pub(crate) fn tensor_differences(&self, vars: &HashMap<String, Tensor>) -> Vec<String> {
        let mut problems = Vec::new();
        for (name, var) in vars {
            match self.tensors.get(name) {
                None => problems.push(format!("missing `{name}`")),
                Some(t) if t.size() != var.size() => problems.push(format!(
                    "`{name}` shape {:?} != variable {:?}",
                    t.size(),
                    var.size()
                )),
                Some(t) if t.kind() != var.kind() => problems.push(format!(
                    "`{name}` dtype {:?} != variable {:?}",
                    t.kind(),
                    var.kind()
                )),
                Some(_) => {}
            }
        }
        problems.extend(
            self.tensors
                .keys()
                .filter(|n| !vars.contains_key(*n))
                .map(|n| format!("unexpected `{n}`")),
        );
        problems.sort();
        problems
    }

    /// A fresh CPU VarStore and model built from the stored configuration, with these weights.
    pub fn build(&self) -> Result<(VarStore, MtaPredNet), CheckpointError> {
        let mut vs = VarStore::new(Device::Cpu);
        let model = MtaPredNet::f_new(&vs.root(), &self.config)
            .map_err(|e| CheckpointError::Config(vec![e.to_string()]))?;
        self.apply(&mut vs, &self.config.clone())?;
        Ok((vs, model))
    }
}
