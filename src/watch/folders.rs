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
    let Ok(sites) = std::fs::read_dir(dir) else {
        return out;
    };
    for site in sites.flatten() {
        let name = site.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || !site.path().is_dir() {
            continue;
        }
        let Ok(epochs) = std::fs::read_dir(site.path()) else {
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
