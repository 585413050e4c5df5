//! `cliffwatch backup` (to be written).

/// Arguments of `cliffwatch backup`.
#[derive(clap::Args)]
pub struct BackupArgs {}

/// Runs `cliffwatch backup`.
pub fn run(_args: BackupArgs) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
