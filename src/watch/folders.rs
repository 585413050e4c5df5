//! The watched directory on disk: which folders are ready, their content hash, their images,
//! and where a folder moves once taken (`.done/`, `.failed/`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// Image file extensions the watcher reads, compared in lower case (`T1.JPG` is an image).
const IMAGE_EXTENSIONS: [&str; 5] = ["jpg", "jpeg", "png", "tif", "tiff"];

/// Folders `<dir>/<site>/<epoch>/` holding `READY` (names starting with `.` skipped), sorted.
pub fn ready_folders(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    for (name, site) in site_dirs(dir) {
        let Ok(epochs) = std::fs::read_dir(&site) else {
            continue;
        };
        for e in epochs.flatten() {
            let en = e.file_name().to_string_lossy().into_owned();
            if !en.starts_with('.') && e.path().join("READY").is_file() {
                out.push((name.clone(), e.path()));
            }
        }
    }
    out.sort();
    out
}

/// The sites' directories `<dir>/<site>/` (names starting with `.` skipped), with their names.
fn site_dirs(dir: &Path) -> Vec<(String, PathBuf)> {
    let Ok(sites) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    sites
        .flatten()
        .map(|site| (site.file_name().to_string_lossy().into_owned(), site.path()))
        .filter(|(name, path)| !name.starts_with('.') && path.is_dir())
        .collect()
}

/// The taken folders `<dir>/<site>/.done/<folder>` (of the sites [`ready_folders`] watches)
/// last written before `cut`: the newest modification time of the folder and of the entries
/// directly in it counts (the watcher writes `identification.json` or `duplicate.txt` into a
/// folder when it takes it). Symbolic links in `.done/` and folders whose times cannot be read
/// are left out. Sorted.
pub fn done_folders_before(dir: &Path, cut: std::time::SystemTime) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for (_, site) in site_dirs(dir) {
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
/// outputs excluded).
pub fn content_hash(folder: &Path) -> std::io::Result<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_file()
                && p.file_name()
                    .is_some_and(|n| !OUTPUT_FILES.iter().any(|o| n == *o))
        })
        .collect();
    files.sort();
    let mut h = Sha256::new();
    for f in files {
        h.update(f.file_name().unwrap_or_default().as_encoded_bytes());
        h.update([0]);
        // streamed: an image file is not held in memory to be hashed
        std::io::copy(&mut std::fs::File::open(&f)?, &mut h)?;
    }
    Ok(hex::encode(h.finalize()))
}

pub(super) fn state_dir(site_dir: &Path) -> PathBuf {
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
    while dest.exists() {
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
    let dest = if dest.exists() {
        free_destination(folder, &sub)
    } else {
        dest
    };
    if let Some(dir) = dest.parent() {
        std::fs::create_dir_all(dir)?;
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
