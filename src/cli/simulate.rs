//! `cliffwatch simulate` (to be written).

/// Arguments of `cliffwatch simulate`.
#[derive(clap::Args)]
pub struct SimulateArgs {}

/// Runs `cliffwatch simulate`.
pub fn run(_args: SimulateArgs) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
