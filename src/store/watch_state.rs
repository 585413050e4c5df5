//! State of the watched directory: each station's latest orientation and the content hashes of the
//! folders taken (see [`crate::watch`]).

use std::collections::BTreeMap;

use chrono::{DateTime, Utc};
use sqlx::{AnyConnection, AnyExecutor};

use super::{timestamp, StoreError};
use cliffwatch_core::photogrammetry::ImageOrientation;

/// The stored orientation of every station of a site, by station (image and station fields empty).
pub async fn orientations(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<BTreeMap<String, ImageOrientation>, StoreError> {
    let rows: Vec<(String, String, String, String)> = sqlx::query_as(
        "SELECT station, camera, rotation, center FROM watch_orientations WHERE site_id = $1 \
         ORDER BY station",
    )
    .bind(site)
    .fetch_all(db)
    .await?;
    let mut out = BTreeMap::new();
    for (station, camera, rotation, center) in rows {
        out.insert(
            station,
            ImageOrientation {
                image: String::new(),
                station: String::new(),
                camera,
                rotation: serde_json::from_str(&rotation)?,
                center: serde_json::from_str(&center)?,
            },
        );
    }
    Ok(out)
}

/// Stores the orientation of `station` found with epoch `epoch`, replacing the stored one unless
/// that was found with a later epoch (by observation time): a folder taken late, holding an older
/// epoch, does not put back an older pose. Epoch ids are numbered per site: both epochs are
/// looked up in `site`. `at`: the transaction's time on the store's clock ([`super::clock`]).
pub async fn set_orientation(
    db: &mut AnyConnection,
    site: &str,
    station: &str,
    o: &ImageOrientation,
    epoch: i64,
    at: DateTime<Utc>,
) -> Result<(), StoreError> {
    let at = timestamp(at);
    sqlx::query(
        "INSERT INTO watch_orientations (site_id, station, camera, rotation, center, epoch_id, updated_at) \
         VALUES ($1, $2, $3, $4, $5, $6, $7) \
         ON CONFLICT (site_id, station) DO UPDATE SET camera = excluded.camera, \
         rotation = excluded.rotation, center = excluded.center, epoch_id = excluded.epoch_id, \
         updated_at = excluded.updated_at \
         WHERE COALESCE((SELECT e.observed_at FROM epochs e \
         WHERE e.site_id = watch_orientations.site_id AND e.id = watch_orientations.epoch_id), '') \
         <= (SELECT e.observed_at FROM epochs e \
         WHERE e.site_id = excluded.site_id AND e.id = excluded.epoch_id)",
    )
    .bind(site)
    .bind(station)
    .bind(&o.camera)
    .bind(serde_json::to_string(&o.rotation)?)
    .bind(serde_json::to_string(&o.center)?)
    .bind(epoch)
    .bind(&at)
    .execute(db)
    .await?;
    Ok(())
}

/// The epoch a folder with content hash `hash` became, if it was taken before.
pub async fn folder_epoch(
    db: impl AnyExecutor<'_>,
    site: &str,
    hash: &str,
) -> Result<Option<i64>, StoreError> {
    Ok(
        sqlx::query_scalar("SELECT epoch_id FROM watch_folders WHERE site_id = $1 AND hash = $2")
            .bind(site)
            .bind(hash)
            .fetch_optional(db)
            .await?,
    )
}

/// Records that the folder with content hash `hash` became epoch `epoch` (idempotent), taken at
/// `at` (the transaction's time on the store's clock, [`super::clock`]).
pub async fn record_folder(
    db: &mut AnyConnection,
    site: &str,
    hash: &str,
    epoch: i64,
    at: DateTime<Utc>,
) -> Result<(), StoreError> {
    let at = timestamp(at);
    sqlx::query(
        "INSERT INTO watch_folders (site_id, hash, epoch_id, taken_at) VALUES ($1, $2, $3, $4) \
         ON CONFLICT (site_id, hash) DO NOTHING",
    )
    .bind(site)
    .bind(hash)
    .bind(epoch)
    .bind(&at)
    .execute(db)
    .await?;
    Ok(())
}
