//! What the watcher keeps between epochs, in the database: the folders taken (by content hash)
//! and the stations' orientations (files of earlier versions are still read).

use std::collections::BTreeMap;
use std::path::Path;

use super::folders::read_state_file;
use crate::store::{self, watch_state, Store, StoreError};
use cliffwatch_core::photogrammetry::ImageOrientation;

/// Orientations from the file of earlier versions (`<site>/.state/orientations.json`), if any.
pub(super) fn legacy_orientations(site_dir: &Path) -> BTreeMap<String, ImageOrientation> {
    read_state_file(site_dir, "orientations.json")
        .and_then(|s| serde_json::from_str::<BTreeMap<String, StoredOrientation>>(&s).ok())
        .map(|m| {
            m.into_iter()
                .map(|(k, v)| (k, v.into_orientation()))
                .collect()
        })
        .unwrap_or_default()
}

/// The stations' orientations: the database's, else the legacy file's.
pub(super) async fn load_orientations(
    store: &Store,
    site: &str,
    site_dir: &Path,
) -> Result<BTreeMap<String, ImageOrientation>, StoreError> {
    let mut all = legacy_orientations(site_dir);
    all.extend(watch_state::orientations(store.reader(), site).await?);
    Ok(all)
}

#[derive(serde::Deserialize)]
struct StoredOrientation {
    camera: String,
    rotation: [[f64; 3]; 3],
    center: [f64; 3],
}

impl StoredOrientation {
    fn into_orientation(self) -> ImageOrientation {
        ImageOrientation {
            image: String::new(),
            station: String::new(),
            camera: self.camera,
            rotation: self.rotation,
            center: self.center,
        }
    }
}

/// Records the stations' orientations (each kept only when no newer epoch's is stored, see
/// [`watch_state::set_orientation`]) and the folder's hash (already recorded in the epoch's
/// transaction unless the same upload was stored before) in one transaction.
pub(super) async fn save_state(
    store: &Store,
    site: &str,
    hash: &str,
    epoch: i64,
    found: &BTreeMap<String, ImageOrientation>,
) -> Result<(), StoreError> {
    let mut tx = store.begin_write_site(site).await?;
    let at = store::clock(&mut tx).await?;
    for (station, o) in found {
        watch_state::set_orientation(&mut tx, site, station, o, epoch, at).await?;
    }
    watch_state::record_folder(&mut tx, site, hash, epoch, at).await?;
    tx.commit().await?;
    Ok(())
}
