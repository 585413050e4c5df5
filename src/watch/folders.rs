//! The watched directory on disk: which folders are ready, their content hash, their images,
//! and where a folder moves once taken (`.done/`, `.failed/`). Nothing outside the directory is
//! followed ([`super::inside`]): a link where a site's or an epoch's folder belongs is refused
//! ([`RefusedEntry`]), and the folders `.done/`, `.failed/` and `.state/` are used only when they
//! are real folders.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::inside::{
    ensure_real_dir, is_real_dir, open_inside, read_to_string_inside, refusal, refused_io,
    write_if_absent, Refused,
};

/// Image file extensions the watcher reads, compared in lower case (`T1.JPG` is an image).
const IMAGE_EXTENSIONS: [&str; 5] = ["jpg", "jpeg", "png", "tif", "tiff"];

/// A link where a site's folder (`<dir>/<site>`) or an epoch's folder (`<dir>/<site>/<epoch>`)
/// belongs: not followed, nothing read through it or written into it. It is logged; an epoch's
/// link in a real site folder also gets a note in that site's `.failed/` ([`RefusedEntry::note`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RefusedEntry {
    /// The entry itself.
    pub path: PathBuf,
    /// Why it is refused.
    pub reason: Refused,
    /// Where its note goes (`<site>/.failed/<entry>.refused.txt`), for an epoch's entry; `None`
    /// for a site's entry, which no folder inside the directory can hold.
    pub note: Option<PathBuf>,
}

/// What one look at the watched directory found.
#[derive(Debug, Default)]
pub struct Scan {
    /// Folders `<dir>/<site>/<epoch>/` holding `READY`, sorted, with their sites.
    pub ready: Vec<(String, PathBuf)>,
    /// Links where a site's or an epoch's folder belongs, sorted.
    pub refused: Vec<RefusedEntry>,
}

/// Looks at `dir`: its sites' folders and their epochs' folders (names starting with `.` skipped,
/// links refused and not followed).
pub fn scan(dir: &Path) -> Scan {
    let (sites, mut refused) = site_dirs(dir);
    let mut ready = Vec::new();
    for (name, site) in sites {
        let Ok(epochs) = std::fs::read_dir(&site) else {
            continue;
        };
        for e in epochs.flatten() {
            let en = e.file_name().to_string_lossy().into_owned();
            if en.starts_with('.') {
                continue;
            }
            // `DirEntry::metadata` does not follow a link
            let Ok(meta) = e.metadata() else {
                continue;
            };
            if meta.is_dir() {
                if std::fs::symlink_metadata(e.path().join("READY")).is_ok() {
                    ready.push((name.clone(), e.path()));
                }
            } else if meta.is_symlink() {
                refused.push(RefusedEntry {
                    path: e.path(),
                    reason: Refused::Symlink { name: en.clone() },
                    note: Some(site.join(".failed").join(format!("{en}.refused.txt"))),
                });
            }
        }
    }
    ready.sort();
    refused.sort_by(|a, b| a.path.cmp(&b.path));
    Scan { ready, refused }
}

/// Folders `<dir>/<site>/<epoch>/` holding `READY` (names starting with `.` skipped, links not
/// followed: see [`scan`]), sorted.
pub fn ready_folders(dir: &Path) -> Vec<(String, PathBuf)> {
    scan(dir).ready
}

/// Logs the entries of `refused` not in `known` (then `known` holds `refused`'s), and writes the
/// note of each that has one and has none yet (never through a link: a `.failed` that is not a
/// real folder gets no note, which is logged).
pub fn report_refused(refused: &[RefusedEntry], known: &mut BTreeSet<PathBuf>) {
    let now: BTreeSet<PathBuf> = refused.iter().map(|r| r.path.clone()).collect();
    for r in refused {
        if !known.contains(&r.path) {
            tracing::warn!(entry = %r.path.display(), reason = %r.reason,
                "watched directory: entry refused, not followed");
        }
        let Some(note) = &r.note else {
            continue;
        };
        let text = format!(
            "{} was not taken: {}\nNothing was read from it or written into it. Remove the link \
             and put the folder itself here.\n",
            r.reason.name(),
            r.reason
        );
        let written = note
            .parent()
            .map_or(Ok(()), ensure_real_dir)
            .and_then(|()| write_if_absent(note, text.as_bytes()));
        if let Err(e) = written {
            if !known.contains(&r.path) {
                tracing::warn!(note = %note.display(), error = %e, "note of a refused entry not written");
            }
        }
    }
    *known = now;
}

/// The sites' directories `<dir>/<site>/` (names starting with `.` skipped), with their names, and
/// the links where a site's directory belongs (refused).
fn site_dirs(dir: &Path) -> (Vec<(String, PathBuf)>, Vec<RefusedEntry>) {
    let Ok(sites) = std::fs::read_dir(dir) else {
        return (Vec::new(), Vec::new());
    };
    let mut out = Vec::new();
    let mut refused = Vec::new();
    for site in sites.flatten() {
        let name = site.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        match site.metadata() {
            Ok(m) if m.is_dir() => out.push((name, site.path())),
            Ok(m) if m.is_symlink() => refused.push(RefusedEntry {
                path: site.path(),
                reason: Refused::Symlink { name },
                note: None,
            }),
            _ => {}
        }
    }
    (out, refused)
}

/// The taken folders `<dir>/<site>/.done/<folder>` (of the sites [`ready_folders`] watches)
/// last written before `cut`: the newest modification time of the folder and of the entries
/// directly in it counts (the watcher writes `identification.json` or `duplicate.txt` into a
/// folder when it takes it). Symbolic links in `.done/` and folders whose times cannot be read
/// are left out. Sorted.
pub fn done_folders_before(dir: &Path, cut: std::time::SystemTime) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for (_, site) in site_dirs(dir).0 {
        // a `.done` that is a link is not followed (its folders would be deleted)
        if !is_real_dir(&site.join(".done")).unwrap_or(false) {
            continue;
        }
        let Ok(done) = std::fs::read_dir(site.join(".done")) else {
            continue;
        };
        for folder in done.flatten() {
            if !folder.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            if last_written(&folder.path()).is_some_and(|t| t < cut) {
                out.push(folder.path());
            }
        }
    }
    out.sort();
    out
}

/// The newest modification time of `folder` and the entries directly in it (not following links).
fn last_written(folder: &Path) -> Option<std::time::SystemTime> {
    let mut newest = std::fs::symlink_metadata(folder).ok()?.modified().ok()?;
    for entry in std::fs::read_dir(folder).ok()? {
        let modified = entry.ok()?.metadata().ok()?.modified().ok()?;
        newest = newest.max(modified);
    }
    Some(newest)
}

/// Files the watcher writes into a folder (not part of its content).
const OUTPUT_FILES: [&str; 4] = ["READY", "error.txt", "identification.json", "duplicate.txt"];

/// sha256 (hex) over the sorted names and bytes of the folder's files (`READY` and the watcher's own
/// outputs excluded; folders in it skipped). A link, a file with several hard links or a special
/// file in the folder is refused (an [`std::io::ErrorKind::InvalidInput`] error naming it),
/// nothing behind it read.
pub fn content_hash(folder: &Path) -> std::io::Result<String> {
    let mut files: Vec<PathBuf> = Vec::new();
    for e in std::fs::read_dir(folder)? {
        let e = e?;
        // `DirEntry::metadata` does not follow a link
        let meta = e.metadata()?;
        if let Some(r) = refusal(&e.file_name().to_string_lossy(), &meta) {
            return Err(refused_io(r));
        }
        if meta.is_file() && !OUTPUT_FILES.iter().any(|o| e.file_name() == *o) {
            files.push(e.path());
        }
    }
    files.sort();
    let mut h = Sha256::new();
    for f in files {
        h.update(f.file_name().unwrap_or_default().as_encoded_bytes());
        h.update([0]);
        // streamed: an image file is not held in memory to be hashed
        std::io::copy(&mut open_inside(&f)?, &mut h)?;
    }
    Ok(hex::encode(h.finalize()))
}

/// The text of the site's file `.state/<name>` of earlier versions, when `.state` is a real folder
/// and the file a regular one ([`open_inside`]); `None` otherwise (a link is logged).
pub(super) fn read_state_file(site_dir: &Path, name: &str) -> Option<String> {
    let dir = state_dir(site_dir);
    let read = is_real_dir(&dir).and_then(|real| {
        real.then(|| read_to_string_inside(&dir.join(name)))
            .transpose()
    });
    match read {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => {
            tracing::warn!(file = %dir.join(name).display(), error = %e, "state file of an earlier version not read");
            None
        }
    }
}

fn state_dir(site_dir: &Path) -> PathBuf {
    site_dir.join(".state")
}

/// Where `folder` would move in `<site>/<sub>/`: its own name, or `<name>.<k>` when that is taken.
pub(super) fn free_destination(folder: &Path, sub: &str) -> PathBuf {
    let site_dir = folder.parent().unwrap_or(Path::new("."));
    let dest_dir = site_dir.join(sub);
    let name = folder
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    let mut dest = dest_dir.join(&name);
    let mut k = 1;
    // a dangling link counts as taken: nothing is moved over or through a link
    while std::fs::symlink_metadata(&dest).is_ok() {
        dest = dest_dir.join(format!("{name}.{k}"));
        k += 1;
    }
    dest
}

/// Moves `folder` to `dest` (a [`free_destination`]), or to the next free name when `dest` was taken
/// in the meantime.
pub(super) fn move_folder(folder: &Path, dest: PathBuf) -> std::io::Result<PathBuf> {
    let sub = dest
        .parent()
        .and_then(Path::file_name)
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let dest = if std::fs::symlink_metadata(&dest).is_ok() {
        free_destination(folder, &sub)
    } else {
        dest
    };
    // `.done/` or `.failed/`: created when absent, refused when a link
    if let Some(dir) = dest.parent() {
        ensure_real_dir(dir)?;
    }
    std::fs::rename(folder, &dest)?;
    Ok(dest)
}

/// Moves `folder` into `<site>/<sub>/`, with a numeric suffix when the name is taken.
pub(super) fn move_to(folder: &Path, sub: &str) -> std::io::Result<PathBuf> {
    move_folder(folder, free_destination(folder, sub))
}

/// The image file of each station of `stations` found in `folder` (`<station>.<extension>`, the
/// extension in any case). Every image file must belong to one of `stations`, and no station may
/// have more than one: an image the watcher would pass over (a station missing from
/// `epoch.json`, a second file of a station) is refused rather than left unused in silence.
/// Errors: [`WatchError::UnlistedImage`], [`WatchError::SeveralImages`].
///
/// [`WatchError::UnlistedImage`]: super::WatchError::UnlistedImage
/// [`WatchError::SeveralImages`]: super::WatchError::SeveralImages
pub(super) fn station_images(
    folder: &Path,
    stations: &[String],
) -> Result<BTreeMap<String, PathBuf>, super::WatchError> {
    let mut per_station: BTreeMap<&str, Vec<String>> = BTreeMap::new();
    for (stem, name) in image_files(folder)? {
        match stations.iter().find(|s| **s == stem) {
            Some(s) => per_station.entry(s.as_str()).or_default().push(name),
            None => return Err(super::WatchError::UnlistedImage(name)),
        }
    }
    per_station
        .into_iter()
        .map(|(station, mut files)| match files.len() {
            1 => Ok((station.to_string(), folder.join(files.remove(0)))),
            _ => Err(super::WatchError::SeveralImages {
                station: station.to_string(),
                files: files.join(", "),
            }),
        })
        .collect()
}

/// The image files of `folder` as (stem, file name), sorted: regular files whose extension, in
/// any case, is one of [`IMAGE_EXTENSIONS`].
fn image_files(folder: &Path) -> std::io::Result<Vec<(String, String)>> {
    let mut files: Vec<(String, String)> = std::fs::read_dir(folder)?
        .flatten()
        .filter(|f| f.file_type().is_ok_and(|t| t.is_file()))
        .filter_map(|f| {
            let path = f.path();
            let ext = path.extension()?.to_str()?.to_ascii_lowercase();
            let stem = path.file_stem()?.to_str()?.to_string();
            let name = f.file_name().to_str()?.to_string();
            IMAGE_EXTENSIONS
                .contains(&ext.as_str())
                .then_some((stem, name))
        })
        .collect();
    files.sort();
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, SystemTime};

    /// Sets the modification time of `path` (file or folder) to `t`.
    fn touch(path: &Path, t: SystemTime) {
        std::fs::File::open(path).unwrap().set_modified(t).unwrap();
    }

    /// A folder with one image, everything in it written at `t`.
    fn folder(path: &Path, t: SystemTime) {
        std::fs::create_dir_all(path).unwrap();
        std::fs::write(path.join("S1.jpg"), b"jpeg").unwrap();
        touch(&path.join("S1.jpg"), t);
        touch(path, t);
    }

    /// With a cut 30 days back, a taken folder written 40 days ago is found; one written 10 days
    /// ago, one whose watcher's file is newer than its images, a failed folder, a folder waiting
    /// to be taken and a link to an old folder are not.
    #[test]
    fn done_folders_are_found_by_their_last_write() {
        let dir = tempfile::tempdir().unwrap();
        let now = SystemTime::now();
        let days = |d: u64| now - Duration::from_secs(d * 86_400);
        let site = dir.path().join("cliff");
        folder(&site.join(".done/old"), days(40));
        folder(&site.join(".done/recent"), days(10));
        folder(&site.join(".done/taken_late"), days(40));
        std::fs::write(site.join(".done/taken_late/identification.json"), b"{}").unwrap();
        touch(&site.join(".done/taken_late"), days(40));
        folder(&site.join(".failed/old"), days(40));
        folder(&site.join("waiting"), days(40));
        folder(&dir.path().join("elsewhere"), days(40));
        std::os::unix::fs::symlink(dir.path().join("elsewhere"), site.join(".done/link")).unwrap();
        touch(&site.join(".done"), days(40));
        assert_eq!(
            done_folders_before(dir.path(), days(30)),
            [site.join(".done/old")]
        );
        assert!(done_folders_before(dir.path(), days(50)).is_empty());
        assert!(done_folders_before(&dir.path().join("missing"), now).is_empty());
    }
}
