//! Every file the stack writes goes through [`write_atomic`]: a temporary file in the target's
//! directory, fsync, rename over the target, fsync of the directory. A reader sees the old file
//! or the new one and a crash (or `kill -9`) leaves no half-written file under the final name.
//! Config files are read by [`read_toml`] and summaries by [`read_json`]; errors name the file
//! (and the key, where the format can).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Why a file could not be written or read; always names the file.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path} is not valid TOML: {message}")]
    Toml { path: PathBuf, message: String },
    #[error("writing {path}: {detail}")]
    Encode { path: PathBuf, detail: String },
    #[error("{path} is not what it should hold: {detail}")]
    Decode { path: PathBuf, detail: String },
}

impl FileError {
    /// True when the file does not exist (a summary a process did not write, say).
    pub fn is_not_found(&self) -> bool {
        matches!(self, Self::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

impl FileError {
    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| Self::Io {
            path: path.to_owned(),
            source,
        }
    }
}

/// Writes `path` through `fill` atomically (see the crate docs), creating its directory.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<std::fs::File>) -> Result<(), FileError>,
) -> Result<(), FileError> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| FileError::io(path)(std::io::Error::other("no file name")))?;
    std::fs::create_dir_all(dir).map_err(FileError::io(dir))?;
    // Hidden, and unique per process: two writers of one file never share a temporary.
    let tmp = dir.join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| {
        let mut w = BufWriter::new(std::fs::File::create(&tmp).map_err(FileError::io(&tmp))?);
        fill(&mut w)?;
        let file = w
            .into_inner()
            .map_err(|e| FileError::io(&tmp)(e.into_error()))?;
        file.sync_all().map_err(FileError::io(&tmp))?;
        std::fs::rename(&tmp, path).map_err(FileError::io(path))?;
        // Persist the rename itself.
        std::fs::File::open(dir)
            .and_then(|d| d.sync_all())
            .map_err(FileError::io(dir))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    write_atomic(path, |w| w.write_all(bytes).map_err(FileError::io(path)))
}

/// Writes `value` as pretty JSON to `path` atomically.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<(), FileError> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(w, value).map_err(|e| FileError::Encode {
            path: path.to_owned(),
            detail: e.to_string(),
        })
    })
}

/// Reads a JSON file written by [`write_json`] into `T`.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, FileError> {
    let bytes = std::fs::read(path).map_err(FileError::io(path))?;
    // The path to the failing field (`control.plans`), which serde_json alone does not name.
    let de = &mut serde_json::Deserializer::from_slice(&bytes);
    serde_path_to_error::deserialize(de).map_err(|e| FileError::Decode {
        path: path.to_owned(),
        detail: format!("{}: {}", e.path(), e.inner()),
    })
}

/// One float32 array of an npz archive: its name, shape and data (row-major).
pub struct NpzArray<'a> {
    pub name: &'a str,
    pub shape: Vec<usize>,
    pub data: &'a [f32],
}

/// Writes float32 arrays as an uncompressed npz archive (numpy's `np.savez` layout) atomically.
pub fn write_npz(path: &Path, arrays: &[NpzArray]) -> Result<(), FileError> {
    let encode = |detail: String| FileError::Encode {
        path: path.to_owned(),
        detail,
    };
    write_atomic(path, |w| {
        let mut npz = ndarray_npy::NpzWriter::new(w);
        for a in arrays {
            let array = ndarray::ArrayViewD::from_shape(a.shape.as_slice(), a.data)
                .map_err(|e| encode(format!("array {}: {e}", a.name)))?;
            npz.add_array(a.name, &array)
                .map_err(|e| encode(format!("array {}: {e}", a.name)))?;
        }
        npz.finish().map_err(|e| encode(e.to_string()))?;
        Ok(())
    })
}

/// Merges `over` into `base`: tables key by key, recursively; anything else replaces (how a
/// config's overrides and a partial sub-table meet their defaults).
pub fn merge_tables(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

/// Reads a TOML file as a table (for configs that are merged or split before they are typed).
pub fn read_table(path: &Path) -> Result<toml::Table, FileError> {
    read_toml(path)
}

/// Reads a TOML file into `T`; the error names the file, and the key and line where TOML can.
pub fn read_toml<T: DeserializeOwned>(path: &Path) -> Result<T, FileError> {
    let text = std::fs::read_to_string(path).map_err(FileError::io(path))?;
    toml::from_str(&text).map_err(|e| FileError::Toml {
        path: path.to_owned(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests;
