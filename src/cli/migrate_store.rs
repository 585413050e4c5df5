//! `cliffwatch migrate-store --from URL --to URL`: moves a whole installation between stores
//! (SQLite ↔ PostgreSQL), offline: stop the daemon first. The target is created or migrated to
//! this version's schema and must hold no site; nothing is written to it when the copy fails.

use anyhow::Context;
use cliffwatch::store::{self, Store, StoreOptions};

/// Arguments of `cliffwatch migrate-store`.
#[derive(clap::Args)]
pub struct MigrateStoreArgs {
    /// The store to copy: sqlite://PATH or postgres://USER:PASSWORD@HOST:PORT/DB.
    #[arg(long)]
    pub from: String,
    /// The empty store to copy into (same forms).
    #[arg(long)]
    pub to: String,
}

/// Runs `cliffwatch migrate-store`.
pub fn run(args: MigrateStoreArgs) -> anyhow::Result<()> {
    if let Some(path) = store::sqlite_path(&args.from) {
        anyhow::ensure!(path.exists(), "no database at {}", path.display());
    }
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let (from, to) = (
        store::redacted_url(&args.from),
        store::redacted_url(&args.to),
    );
    runtime.block_on(async {
        let options = StoreOptions::default();
        let source = Store::connect(&args.from, &options)
            .await
            .with_context(|| format!("opening {from}"))?;
        let target = Store::connect(&args.to, &options)
            .await
            .with_context(|| format!("opening {to}"))?;
        let copied = store::copy::copy_all(&source, &target)
            .await
            .with_context(|| format!("copying {from} to {to}"))?;
        source.close().await;
        target.close().await;
        for (table, rows) in &copied {
            eprintln!("{table:>20} {rows:>10} rows");
        }
        eprintln!("{from} copied to {to}");
        anyhow::Ok(())
    })
}
