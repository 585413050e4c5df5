//! `cliffwatch serve` (to be written).

/// Arguments of `cliffwatch serve`.
#[derive(clap::Args)]
pub struct ServeArgs {}

/// Runs `cliffwatch serve`.
pub fn run(_args: ServeArgs) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
