//! The watched directory's retention: the folders it took (`<site>/.done/<folder>`, the images)
//! last written more than `watch_done_retention_days` ago are deleted. `.failed/` folders stay
//! for staff to look at; the epoch pages then draw the detections without the image. Scheduled
//! by the daemon (hourly, on one node at a time).

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use crate::shutdown::Shutdown;
use crate::store::{Store, StoreError};
use crate::watch::folders;

/// How often the pass runs.
const EVERY: Duration = Duration::from_secs(3600);

/// Deletes every taken folder of the watched directory `dir` last written more than `retention`
/// before `now` ([`folders::done_folders_before`]). Returns how many went; a folder that cannot
/// be deleted is logged and left for the next pass, one already gone (another node) is skipped.
pub fn prune_done_folders(dir: &Path, retention: Duration, now: SystemTime) -> usize {
    let Some(cut) = now.checked_sub(retention) else {
        return 0;
    };
    let mut pruned = 0;
    for folder in folders::done_folders_before(dir, cut) {
        match std::fs::remove_dir_all(&folder) {
            Ok(()) => pruned += 1,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                tracing::warn!(folder = %folder.display(), error = %e, "deleting a taken folder failed")
            }
        }
    }
    pruned
}

/// One pass on the node that holds the job lock ([`Store::try_job_lock`]): deletes the taken
/// folders of `dir` older than `keep`. Returns how many went.
async fn prune_once(store: &Store, dir: &Path, keep: Duration) -> Result<u64, StoreError> {
    let Some(_held) = store.try_job_lock("watch retention").await? else {
        return Ok(0);
    };
    let dir = dir.to_path_buf();
    tokio::task::spawn_blocking(move || prune_done_folders(&dir, keep, SystemTime::now()))
        .await
        .map(|n| n as u64)
        .map_err(|e| StoreError::Io(std::io::Error::other(e)))
}

/// Deletes the taken folders of `dir` older than `keep` at start and every hour until shutdown.
pub async fn run(store: Store, dir: PathBuf, keep: Duration, shutdown: Shutdown) {
    loop {
        match prune_once(&store, &dir, keep).await {
            Ok(0) => {}
            Ok(n) => {
                metrics::counter!("cliffwatch_watch_folders_pruned_total").increment(n);
                tracing::info!(
                    deleted = n,
                    "retention: deleted old taken folders of the watched directory"
                );
            }
            Err(e) => tracing::warn!(
                error = %e,
                "retention: deleting old taken folders of the watched directory failed"
            ),
        }
        if shutdown.sleep(EVERY).await {
            break;
        }
    }
    tracing::info!("watch retention stopped");
}
