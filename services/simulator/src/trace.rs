//! The car's path with who drove it, as CSV (`step,episode,x,y,lateral_m,source`), every
//! `every` steps: for the run's lap-trace picture.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::Context;
use mtanet_ipc::CommandSource;
use mtanet_scenes::GroundTruth;

pub struct Trace {
    out: BufWriter<File>,
    every: u64,
}

impl Trace {
    pub fn create(path: &Path, every: u64) -> anyhow::Result<Self> {
        let file =
            File::create(path).with_context(|| format!("creating the trace {}", path.display()))?;
        let mut out = BufWriter::new(file);
        writeln!(out, "step,episode,x,y,lateral_m,source")?;
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
            writeln!(
                self.out,
                "{step},{episode},{:.4},{:.4},{:.4},{}",
                t.x,
                t.y,
                t.lateral_m,
                source.name()
            )?;
        }
        Ok(())
    }

    pub fn finish(mut self) -> anyhow::Result<()> {
        self.out.flush().context("writing the trace")
    }
}
