//! `mta synth`: writes the synthetic action-conditioned dataset used by the model tests.

#[derive(Debug, clap::Args)]
pub struct SynthArgs {}

pub fn run(_args: SynthArgs) -> anyhow::Result<()> {
    anyhow::bail!("mta synth: not implemented yet")
}
