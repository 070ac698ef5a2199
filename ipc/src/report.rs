//! Run summaries as JSON files, written atomically (temp file + rename) so a reader never sees a
//! half-written report, even if the writer is killed.

use std::path::Path;

use serde::Serialize;

/// Writes `value` as pretty JSON to `path`, creating the parent directory.
pub fn write_json(path: &Path, value: &impl Serialize) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let tmp = tempfile::NamedTempFile::new_in(dir)?;
    serde_json::to_writer_pretty(&tmp, value)?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}
