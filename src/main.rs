//! The `cliffwatch` command line: `serve`, `adjust`, `simulate`, `backup`, `migrate-store`.

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
    /// Generate simulated epochs with truth.
    Simulate(cli::simulate::SimulateArgs),
    /// Take a consistent online copy of the database.
    Backup(cli::backup::BackupArgs),
    /// Copy a whole installation into an empty store (SQLite <-> PostgreSQL), offline.
    MigrateStore(cli::migrate_store::MigrateStoreArgs),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Serve(args) => cli::serve::run(args),
        Command::Adjust(args) => cli::adjust::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Backup(args) => cli::backup::run(args),
        Command::MigrateStore(args) => cli::migrate_store::run(args),
    }
}
