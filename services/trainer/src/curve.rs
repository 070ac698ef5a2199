//! The learning curve: one JSON line per accepted update, appended to `[trainer] learning_log`
//! (`mta up` puts it in the run folder as `learning.jsonl`; `mta plot` draws it). A resumed
//! trainer appends to the same file, so the curve of a run that was restarted stays whole.
//! A failed write is logged once and the curve stops; training goes on (a full disk must not end
//! the learning).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
pub use mtanet_summaries::curve::{CurvePoint, read};

fn ends_torn(file: &mut File) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    if file.metadata()?.len() == 0 {
        return Ok(false);
    }
    file.seek(SeekFrom::End(-1))?;
    let mut last = [0u8];
    file.read_exact(&mut last)?;
    Ok(last[0] != b'\n')
}

pub struct Curve {
    path: PathBuf,
    out: Option<BufWriter<File>>,
    start: Instant,
}

impl Curve {
    /// Opens `path` for appending (creating its folder); an error here is the operator's to see
    /// at start.
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating the folder of {}", path.display()))?;
        }
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .read(true)
            .open(path)
            .with_context(|| format!("opening trainer.learning_log {}", path.display()))?;
        // A line torn by a killed predecessor stays a line of its own.
        if ends_torn(&mut file)? {
            file.write_all(b"\n")?;
        }
        Ok(Self {
            path: path.to_owned(),
            out: Some(BufWriter::new(file)),
            start: Instant::now(),
        })
    }

    pub fn wall_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Appends one line (flushed: a killed trainer loses at most the line being written).
    pub fn record(&mut self, point: &CurvePoint) {
        let Some(out) = self.out.as_mut() else {
            return;
        };
        let res = serde_json::to_writer(&mut *out, point)
            .map_err(std::io::Error::from)
            .and_then(|_| out.write_all(b"\n"))
            .and_then(|_| out.flush());
        if let Err(e) = res {
            tracing::error!(path = %self.path.display(), "the learning log stops here: {e}");
            self.out = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(step: u64) -> CurvePoint {
        CurvePoint {
            step,
            wall_s: 0.5,
            loss: 0.25,
            grad_norm: 1.5,
            clipped: true,
            update_ms: 200.0,
            replay_sequences: 64,
            chunks_received: 70,
            chunks_lost: 0,
            steps_received: 1400,
            probe: Some(0.75),
        }
    }

    #[test]
    fn appends_across_restarts_and_reads_back_skipping_a_torn_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run/learning.jsonl");
        let mut c = Curve::open(&path).unwrap();
        c.record(&p(1));
        c.record(&p(2));
        drop(c);
        // A trainer killed mid-line, then restarted: the new process appends after the tear.
        std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .unwrap()
            .write_all(b"{\"step\":3,\"wal")
            .unwrap();
        let mut c = Curve::open(&path).unwrap();
        c.record(&p(4));
        drop(c);
        let (points, bad) = read(&path).unwrap();
        assert_eq!(points.iter().map(|p| p.step).collect::<Vec<_>>(), [1, 2, 4]);
        assert_eq!(bad, 1, "the torn line is skipped, and only it");
        assert_eq!(points[0], p(1));
    }

    #[test]
    fn an_unwritable_log_is_an_error_at_open() {
        let dir = tempfile::tempdir().unwrap();
        // A folder where the file should be.
        let e = Curve::open(dir.path())
            .err()
            .expect("a folder is not a log");
        assert!(format!("{e:#}").contains("learning_log"), "{e:#}");
    }
}
