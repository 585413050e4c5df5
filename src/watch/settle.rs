//! When a ready folder may be taken: once its files have stopped changing. `READY` is the
//! contract's signal, but a copy does not always write it last: rsync sends a folder's files in
//! name order, and `READY` sorts before `epoch.json` and lower-case station names. A folder is
//! therefore taken only when the names, sizes and times of all its entries (hidden ones too, such
//! as rsync's partial files) are the same as at least [`super::WatchOptions::settle`] earlier.
//! Compared between scans of this process, so the clocks of a network share do not matter.

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// One entry of a folder as the settle rule compares it: name, size in bytes, modification time
/// and (Unix) status-change time, which a copy that restores modification times still moves.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Stamp {
    name: OsString,
    len: u64,
    modified: Option<SystemTime>,
    changed: (i64, i64),
}

/// The stamps of every entry of `folder`, sorted by name; `None` when it cannot be listed (it
/// moved, or is being removed).
fn stamps(folder: &Path) -> Option<Vec<Stamp>> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(folder).ok()?.flatten() {
        let Ok(m) = e.metadata() else {
            return None;
        };
        #[cfg(unix)]
        let changed = {
            use std::os::unix::fs::MetadataExt;
            (m.ctime(), m.ctime_nsec())
        };
        #[cfg(not(unix))]
        let changed = (0, 0);
        out.push(Stamp {
            name: e.file_name(),
            len: m.len(),
            modified: m.modified().ok(),
            changed,
        });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Some(out)
}

/// The ready folders seen but not yet settled, with their stamps and since when they have them.
#[derive(Debug, Default)]
pub struct Settling {
    seen: HashMap<PathBuf, (Vec<Stamp>, Instant)>,
}

/// What [`Settling::take`] decided for one scan.
#[derive(Debug)]
pub struct Settled {
    /// The folders to take now, in the order given.
    pub ready: Vec<(String, PathBuf)>,
    /// When the earliest of the others may have settled (a rescan then takes it).
    pub next_check: Option<Instant>,
}

impl Settling {
    /// Which of the `ready` folders (`(site, folder)`) have had the same entries for at least
    /// `settle` by `now`; the others are remembered with their entries. With `settle` zero every
    /// listable folder is taken at once. Folders no longer ready are forgotten.
    pub fn take(
        &mut self,
        ready: Vec<(String, PathBuf)>,
        settle: Duration,
        now: Instant,
    ) -> Settled {
        let mut taken = Vec::new();
        let mut next_check: Option<Instant> = None;
        let mut still = HashMap::new();
        for (site, folder) in ready {
            let Some(now_stamps) = stamps(&folder) else {
                continue;
            };
            let since = match self.seen.remove(&folder) {
                Some((before, since)) if before == now_stamps => since,
                _ => now,
            };
            if now.duration_since(since) >= settle {
                taken.push((site, folder));
            } else {
                let due = since + settle;
                next_check = Some(next_check.map_or(due, |n| n.min(due)));
                still.insert(folder, (now_stamps, since));
            }
        }
        self.seen = still;
        Settled {
            ready: taken,
            next_check,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder_with(files: &[(&str, &[u8])]) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("site").join("e1");
        std::fs::create_dir_all(&folder).unwrap();
        for (name, bytes) in files {
            std::fs::write(folder.join(name), bytes).unwrap();
        }
        (dir, folder)
    }

    #[test]
    fn a_folder_is_taken_once_its_files_stayed_the_same_for_the_settle_time() {
        let (_dir, folder) = folder_with(&[("READY", b""), ("T1.jpg", b"part")]);
        let ready = || vec![("site".to_string(), folder.clone())];
        let settle = Duration::from_secs(2);
        let t0 = Instant::now();
        let mut s = Settling::default();
        let first = s.take(ready(), settle, t0);
        assert!(first.ready.is_empty(), "seen for the first time");
        assert_eq!(first.next_check, Some(t0 + settle));
        let early = s.take(ready(), settle, t0 + Duration::from_secs(1));
        assert!(early.ready.is_empty(), "unchanged for 1 s only");
        // The copy goes on: the image grows and epoch.json arrives; the clock starts again.
        std::fs::write(folder.join("T1.jpg"), b"part and the rest").unwrap();
        let grown = s.take(ready(), settle, t0 + Duration::from_secs(3));
        assert!(grown.ready.is_empty(), "an entry changed");
        assert_eq!(grown.next_check, Some(t0 + Duration::from_secs(5)));
        std::fs::write(folder.join("epoch.json"), b"{}").unwrap();
        let added = s.take(ready(), settle, t0 + Duration::from_secs(5));
        assert!(added.ready.is_empty(), "an entry was added");
        let done = s.take(ready(), settle, t0 + Duration::from_secs(7));
        assert_eq!(done.ready, ready());
        assert_eq!(done.next_check, None);
    }

    #[test]
    fn without_a_settle_time_a_ready_folder_is_taken_at_once() {
        let (_dir, folder) = folder_with(&[("READY", b"")]);
        let mut s = Settling::default();
        let ready = vec![("site".to_string(), folder.clone())];
        let out = s.take(ready.clone(), Duration::ZERO, Instant::now());
        assert_eq!(out.ready, ready);
    }

    #[test]
    fn a_folder_that_went_away_is_forgotten() {
        let (_dir, folder) = folder_with(&[("READY", b"")]);
        let mut s = Settling::default();
        let t0 = Instant::now();
        let settle = Duration::from_secs(2);
        s.take(vec![("site".into(), folder.clone())], settle, t0);
        std::fs::remove_dir_all(&folder).unwrap();
        let out = s.take(vec![("site".into(), folder)], settle, t0 + settle);
        assert!(out.ready.is_empty() && out.next_check.is_none());
        assert!(s.seen.is_empty());
    }
}
