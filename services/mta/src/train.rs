//! `mta train`: offline training of MTA-PredNet from a dataset `.npz` (owned by the models work).

#[derive(Debug, clap::Args)]
pub struct TrainArgs {}

pub fn run(_args: TrainArgs) -> anyhow::Result<()> {
    anyhow::bail!("mta train: not implemented yet")
}
