//! Opening the store: either backend's pools and migrations ([`super::pool`]), then the packing
//! of the series of sites stored before the packed blocks existed ([`series_blocks::backfill`]).

use std::path::Path;

use super::error::StoreError;
use super::pool::{redacted_url, sqlite_path, Store, StoreOptions};
use super::series::blocks as series_blocks;

impl Store {
    /// Opens the database of `url`: `sqlite://PATH` (the file is created when missing) or
    /// `postgres://USER@HOST:PORT/DB`; applies that backend's migrations.
    pub async fn connect(url: &str, options: &StoreOptions) -> Result<Store, StoreError> {
        if let Some(path) = sqlite_path(url) {
            return Store::open(path, options).await;
        }
        if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            return Store::open_postgres(url, options).await;
        }
        Err(StoreError::Url(redacted_url(url)))
    }

    /// Opens (creating when missing) the SQLite file, applies the migrations, packs the series
    /// of sites stored before migration 20261122000700 ([`series_blocks::backfill`]).
    pub async fn open(path: &Path, options: &StoreOptions) -> Result<Store, StoreError> {
        let store = Store::open_sqlite_pools(path, options).await?;
        series_blocks::backfill(&store).await?;
        Ok(store)
    }

    /// Opens a PostgreSQL database, applies its migrations and packs the series of sites stored
    /// before migration 20261125000300 ([`series_blocks::backfill`]). Writes go through a pool of
    /// [`StoreOptions::write_connections`]; the advisory locks of [`Store::begin_write_site`]
    /// decide which of them may run side by side.
    async fn open_postgres(url: &str, options: &StoreOptions) -> Result<Store, StoreError> {
        let store = Store::open_postgres_pools(url, options).await?;
        series_blocks::backfill(&store).await?;
        Ok(store)
    }
}
