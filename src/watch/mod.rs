//! The watched directory of the contract: `<watch_dir>/<site>/<epoch>/` holds one image per station
//! (`<station>.jpg|.png|.tif`) and an `epoch.json` in the upload form; the folder is taken when `READY`
//! appears. Each image is decoded and searched for targets, and the targets are named, on
//! blocking threads (`spawn_blocking`). They are identified: stations with ≥ 4 seed
//! observations in `epoch.json` together, by multi-view matching
//! that needs the approximations only to name the targets ([`cliffwatch_core::detect::first_epoch`]; a station
//! seeded alone, or stations that do not share 4 seeded targets, from their own seeds,
//! [`cliffwatch_core::detect::identify`]); stations without seeds from the orientation the watcher kept from
//! their previous epoch. The epoch is ingested exactly as an upload
//! ([`crate::service::ingest::ingest_watched`]: the counts below are stored with its report),
//! and the stations' orientations for the next epoch are resected from its adjusted coordinates.
//! A folder is taken once `READY` is there and its files have stopped changing for
//! [`WatchOptions::settle`] ([`Settling`]): a copy may write `READY` before the rest.
//! The folder then moves to `<site>/.done/` with `identification.json` (per station: method,
//! detected, identified, ambiguous, unmatched, where the image is kept and every detection with its
//! name, which the report keeps too, so the dashboard can draw them over the image) or, with
//! `error.txt`, to `<site>/.failed/`;
//! when too few targets can be named, `error.txt` gives the same counts, the likely cause and what
//! to add. A folder whose content hash (sha256 of its files' names and bytes, the watcher's own
//! outputs excluded) is in the database ([`crate::store::watch_state`]) is never ingested
//! again; the stations' orientations are kept there too, so the state is backed up and restored with
//! the database. (Files `<site>/.state/ingested` and `<site>/.state/orientations.json` of earlier
//! versions are still read, never written.) The folder's hash is written in the epoch's own
//! transaction, so a daemon that dies right after the commit finds the folder taken on restart
//! (it moves to `.done/` with `duplicate.txt`). The orientations are written after it, each only
//! when no later epoch's orientation of that station is stored: a folder taken late, holding an
//! older epoch, leaves the newer poses.
//!
//! Watching: `notify` events and a periodic rescan (events can be lost, e.g. on network shares).
//!
//! The directory stays inside ([`inside`]): nothing outside it is read or written. A link, a file
//! with several hard links or a special file in an epoch's folder sends the folder to `.failed/`
//! with `error.txt` naming it; a link where a site's or an epoch's folder belongs is neither
//! followed nor moved, but logged ([`RefusedEntry`]), with a note `<entry>.refused.txt` in the
//! site's `.failed/` for an epoch's link.
//!
//! The files: `folders.rs` (what the directory holds and where a folder moves), `stations.rs`
//! (one station's image: detection and the counts of its targets), `image_file.rs` (reading an
//! image file within the size limit), `naming.rs` (which detected
//! target is which point), `settle.rs` (when a ready folder has stopped changing), `ingest.rs` (one folder taken, the use case), `inside.rs` (nothing outside the directory
//! read or written: links, hard links and special files refused), `state.rs` (what the
//! watcher keeps between epochs: the folders taken and the stations' orientations), and here the
//! loop that scans.

mod error;
pub(crate) mod folders;
pub(crate) mod image_file;
pub(crate) mod ingest;
pub mod inside;
mod naming;
mod options;
mod settle;
mod state;
mod stations;

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::time::Duration;

pub use error::WatchError;
pub use folders::{content_hash, ready_folders, scan, RefusedEntry, Scan};
pub use ingest::take_folder;
pub use options::WatchOptions;
pub use settle::{Settled, Settling};

use crate::shutdown::Shutdown;
use crate::store::Store;

/// Takes every ready folder once (sequentially), at once, whether or not its files are still
/// changing ([`run`] waits for them to settle first). Several nodes may watch one shared
/// directory: each folder is claimed ([`Store::try_job_lock`] on its site and name) and held until
/// it has moved to `.done/` or `.failed/`; a folder another node holds, or has already moved, is
/// left. Refused entries ([`RefusedEntry`]) are logged and noted, never followed.
pub async fn scan_once(store: &Store, opts: &WatchOptions) -> Vec<std::io::Result<PathBuf>> {
    let found = scan(&opts.dir);
    folders::report_refused(&found.refused, &mut BTreeSet::new());
    take_all(store, opts, found.ready).await
}

/// Takes each of `ready` (`(site, folder)`) as [`scan_once`] does.
async fn take_all(
    store: &Store,
    opts: &WatchOptions,
    ready: Vec<(String, PathBuf)>,
) -> Vec<std::io::Result<PathBuf>> {
    let mut out = Vec::new();
    for (site, folder) in ready {
        let name = folder.file_name().unwrap_or_default().to_string_lossy();
        let claim = match store.try_job_lock(&format!("watch {site}/{name}")).await {
            Ok(Some(claim)) => claim,
            Ok(None) => continue,
            Err(e) => {
                out.push(Err(std::io::Error::other(e)));
                continue;
            }
        };
        // still a real folder (a link is never followed)
        if std::fs::symlink_metadata(&folder).is_ok_and(|m| m.is_dir()) {
            let taken = take_folder(store, &site, &folder, opts).await;
            let outcome = match &taken {
                Ok(to) if to.components().any(|c| c.as_os_str() == ".failed") => "failed",
                Ok(_) => "done",
                Err(_) => "error",
            };
            metrics::counter!("cliffwatch_watch_folders_total", "site" => site.clone(), "outcome" => outcome)
                .increment(1);
            out.push(taken);
        }
        drop(claim);
    }
    out
}

/// Watches `opts.dir` until shutdown: a scan at start, on every file-system event, every
/// `opts.rescan`, and when a ready folder whose files were still changing may have settled
/// ([`Settling`], `opts.settle`). A refused entry is logged when first seen, not at every scan.
pub async fn run(store: Store, opts: WatchOptions, shutdown: Shutdown) -> Result<(), WatchError> {
    use notify::Watcher;
    let (tx, mut rx) = tokio::sync::mpsc::channel::<()>(16);
    // links are not followed by the events either
    let mut watcher = notify::RecommendedWatcher::new(
        move |_res: notify::Result<notify::Event>| {
            let _ = tx.try_send(());
        },
        notify::Config::default().with_follow_symlinks(false),
    )
    .map_err(|e| WatchError::Io(std::io::Error::other(e)))?;
    if let Err(e) = watcher.watch(&opts.dir, notify::RecursiveMode::Recursive) {
        tracing::warn!(error = %e, "file-system events unavailable; rescanning only");
    }
    let mut tick = tokio::time::interval(opts.rescan);
    let mut settling = Settling::default();
    let mut refused = BTreeSet::new();
    let mut next_check: Option<tokio::time::Instant> = None;
    loop {
        let settled = async {
            match next_check {
                Some(at) => tokio::time::sleep_until(at).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            _ = shutdown.requested() => return Ok(()),
            _ = tick.tick() => {}
            _ = settled => {}
            Some(()) = rx.recv() => {
                // let the writer finish its burst of events
                tokio::time::sleep(Duration::from_millis(200)).await;
                while rx.try_recv().is_ok() {}
            }
        }
        let dir = opts.dir.clone();
        let settle = opts.settle;
        let (returned, known, decided) = tokio::task::spawn_blocking(move || {
            let found = scan(&dir);
            folders::report_refused(&found.refused, &mut refused);
            let decided = settling.take(found.ready, settle, std::time::Instant::now());
            (settling, refused, decided)
        })
        .await
        .map_err(|e| WatchError::Io(std::io::Error::other(e)))?;
        settling = returned;
        refused = known;
        next_check = decided.next_check.map(tokio::time::Instant::from_std);
        for r in take_all(&store, &opts, decided.ready).await {
            if let Err(e) = r {
                tracing::warn!(error = %e, "watched folder could not be moved");
            }
        }
    }
}
