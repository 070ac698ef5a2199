//! The car's path with who drove it ([`mtanet_summaries::rows::TraceRow`], CSV), every
//! `every` steps: for the run's lap-trace picture and the experiments' takeover time.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use anyhow::Context;
use mtanet_ipc::CommandSource;
use mtanet_scenes::GroundTruth;
use mtanet_summaries::rows::{self, TraceRow};

pub struct Trace {
    out: csv::Writer<BufWriter<File>>,
    every: u64,
}

impl Trace {
    pub fn create(path: &Path, every: u64) -> anyhow::Result<Self> {
        let file =
            File::create(path).with_context(|| format!("creating the trace {}", path.display()))?;
        let out = rows::writer::<TraceRow, _>(BufWriter::new(file)).context("writing the trace")?;
        Ok(Self {
            out,
            every: every.max(1),
        })
    }

    pub fn record(
        &mut self,
        step: u64,
        episode: u32,
        t: &GroundTruth,
        source: CommandSource,
    ) -> anyhow::Result<()> {
        if step % self.every == 0 {
            let row = TraceRow::new(step, episode, t.x, t.y, t.lateral_m, source.name());
            self.out.serialize(row).context("writing the trace")?;
        }
        Ok(())
    }

    pub fn finish(mut self) -> anyhow::Result<()> {
        self.out.flush().context("writing the trace")
    }
}
