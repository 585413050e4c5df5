//! The `cliffwatch` command line: `serve`, `adjust`, `detect`, `simulate`, `plan`, `backup`,
//! `migrate-store`.

mod cli;

use clap::{Parser, Subcommand};

/// cliffwatch: watches rock cliffs for movement.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the daemon (HTTP API, watched directory, webhook delivery).
    Serve(cli::serve::ServeArgs),
    /// Adjust one epoch file and print the adjustment report (JSON).
    Adjust(cli::adjust::AdjustArgs),
    /// Detect and centre the targets of images; one JSON line per image.
    Detect(cli::detect::DetectArgs),
    /// Generate simulated epochs with truth.
    Simulate(cli::simulate::SimulateArgs),
    /// Predict the precision and the minimum detectable displacement of a planned camera network.
    Plan(cli::plan::PlanArgs),
    /// Take a consistent online copy of the database.
    Backup(cli::backup::BackupArgs),
    /// Copy a whole installation into an empty store (SQLite <-> PostgreSQL), offline.
    MigrateStore(cli::migrate_store::MigrateStoreArgs),
}

fn main() -> anyhow::Result<()> {
    let result = match Cli::parse().command {
        Command::Serve(args) => cli::serve::run(args),
        Command::Adjust(args) => cli::adjust::run(args),
        Command::Detect(args) => cli::detect::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Plan(args) => cli::plan::run(args),
        Command::Backup(args) => cli::backup::run(args),
        Command::MigrateStore(args) => cli::migrate_store::run(args),
    };
    match result {
        Err(e) if reader_went_away(&e) => Ok(()),
        other => other,
    }
}

/// Whether the error is a write into a pipe whose reader has gone (`cliffwatch adjust … | head`):
/// the reader took what it wanted, so the command ends quietly, as Unix tools do.
fn reader_went_away(e: &anyhow::Error) -> bool {
    use std::io::ErrorKind::BrokenPipe;
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == BrokenPipe)
            || cause
                .downcast_ref::<serde_json::Error>()
                .is_some_and(|j| j.io_error_kind() == Some(BrokenPipe))
    })
}
