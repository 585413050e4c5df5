//! The watched directory stays inside: the watcher reads and writes nothing outside it. A symbolic
//! link (to a folder or a file), a file with more than one hard link (its other name may be outside
//! the directory) and a special file (FIFO, socket, device) are refused, never followed, opened or
//! read. Files are opened with `O_NOFOLLOW | O_NONBLOCK` and checked again on the open descriptor,
//! so a file swapped for a link or a FIFO after the folder was listed is refused too, and a FIFO
//! never blocks the watcher. The watcher's own files are written under a fresh name and renamed
//! into place: a link or hard link standing where `error.txt` goes is replaced, not written
//! through, and a file is never left half-written.
//!
//! Not covered: a folder of the path swapped for a link between its check and the open of a file
//! in it (the components above the file are checked, not held open).

use std::fs::{File, Metadata, OpenOptions};
use std::io::Write;
use std::os::unix::fs::{FileTypeExt, MetadataExt, OpenOptionsExt};
use std::path::Path;

/// Why an entry of the watched directory is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    /// A symbolic link: it may lead outside the watched directory, so it is not followed.
    #[error("{name} is a symbolic link: the watcher reads nothing outside the watched directory, so links are not followed; copy the folder or file itself instead of linking it")]
    Symlink {
        /// The entry's name.
        name: String,
    },
    /// A regular file with more than one hard link: another name of it may be outside.
    #[error("{name} has {links} hard links: one of them may be outside the watched directory, so it is not read; copy the file instead of linking it")]
    HardLinks {
        /// The entry's name.
        name: String,
        /// Its number of hard links.
        links: u64,
    },
    /// A FIFO, socket or device: not a file the watcher reads.
    #[error("{name} is a {kind}, not a regular file: remove it")]
    Special {
        /// The entry's name.
        name: String,
        /// `FIFO (named pipe)`, `socket`, `character device` or `block device`.
        kind: &'static str,
    },
}

impl Refused {
    /// The refused entry's name.
    pub fn name(&self) -> &str {
        match self {
            Refused::Symlink { name }
            | Refused::HardLinks { name, .. }
            | Refused::Special { name, .. } => name,
        }
    }
}

/// Why `name`, of metadata `meta` (not following links), is refused; `None` for a directory or a
/// regular file with one link.
pub fn refusal(name: &str, meta: &Metadata) -> Option<Refused> {
    let t = meta.file_type();
    let name = name.to_string();
    if t.is_symlink() {
        return Some(Refused::Symlink { name });
    }
    if t.is_dir() {
        return None;
    }
    if t.is_file() {
        return (meta.nlink() > 1).then(|| Refused::HardLinks {
            name,
            links: meta.nlink(),
        });
    }
    let kind = if t.is_fifo() {
        "FIFO (named pipe)"
    } else if t.is_socket() {
        "socket"
    } else if t.is_char_device() {
        "character device"
    } else if t.is_block_device() {
        "block device"
    } else {
        "special file"
    };
    Some(Refused::Special { name, kind })
}

/// The first refused entry of `folder` (in name order), if any: every entry is looked at without
/// following links.
pub fn check_folder(folder: &Path) -> std::io::Result<Option<Refused>> {
    let mut entries: Vec<_> = std::fs::read_dir(folder)?.collect::<Result<_, _>>()?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        // `DirEntry::metadata` does not follow a link
        let meta = e.metadata()?;
        if let Some(r) = refusal(&e.file_name().to_string_lossy(), &meta) {
            return Ok(Some(r));
        }
    }
    Ok(None)
}

/// The name of `path` for messages.
fn name_of(path: &Path) -> String {
    path.file_name()
        .unwrap_or(path.as_os_str())
        .to_string_lossy()
        .into_owned()
}

/// Opens the regular file `path` for reading without following a link at its end, without
/// blocking on a FIFO, and refuses (as [`std::io::ErrorKind::InvalidInput`] holding a
/// [`Refused`]) what is not a regular file with one link.
pub fn open_inside(path: &Path) -> std::io::Result<File> {
    let opened = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path);
    let file = match opened {
        Ok(f) => f,
        Err(e) if e.raw_os_error() == Some(libc::ELOOP) => {
            return Err(refused_io(Refused::Symlink {
                name: name_of(path),
            }))
        }
        Err(e) => return Err(e),
    };
    let meta = file.metadata()?;
    match refusal(&name_of(path), &meta) {
        Some(r) => Err(refused_io(r)),
        None if meta.is_dir() => Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{} is a folder, not a file", name_of(path)),
        )),
        None => Ok(file),
    }
}

/// `r` as an I/O error (kind [`std::io::ErrorKind::InvalidInput`]), its message `r`'s.
pub fn refused_io(r: Refused) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidInput, r)
}

/// The text of the regular file `path`, opened as [`open_inside`] does.
pub fn read_to_string_inside(path: &Path) -> std::io::Result<String> {
    let mut text = String::new();
    std::io::Read::read_to_string(&mut open_inside(path)?, &mut text)?;
    Ok(text)
}

/// Whether `path` is a real directory (`false` when it does not exist); an error when it is a
/// link or anything else.
pub fn is_real_dir(path: &Path) -> std::io::Result<bool> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => Ok(true),
        Ok(m) => Err(refused_io(refusal(&name_of(path), &m).unwrap_or_else(
            || Refused::Special {
                name: name_of(path),
                kind: "file where a folder belongs",
            },
        ))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(e),
    }
}

/// Makes sure `path` is a real directory: creates it (its parent must exist) when absent, and
/// refuses a link or file standing there.
pub fn ensure_real_dir(path: &Path) -> std::io::Result<()> {
    if is_real_dir(path)? {
        return Ok(());
    }
    match std::fs::create_dir(path) {
        Ok(()) => Ok(()),
        // created in the meantime (another node): whatever it is, checked again
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => is_real_dir(path).map(|_| ()),
        Err(e) => Err(e),
    }
}

/// Writes `bytes` as the file `path`: into a new file of a fresh name in the same folder, then
/// renamed over `path`, so whatever stood at `path` (a link, a hard link) is replaced rather than
/// written through, and a reader sees the old file or the whole new one.
pub fn write_replacing(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let tmp = dir.join(format!(
        ".{}.{:016x}.tmp",
        name_of(path),
        rand::random::<u64>()
    ));
    let written = write_new(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// Writes `bytes` into the new file `path` (`create_new`, `O_EXCL`: nothing standing there is
/// followed or reused) and syncs it.
fn write_new(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut f = OpenOptions::new().write(true).create_new(true).open(path)?;
    f.write_all(bytes)?;
    f.sync_all()
}

/// Writes `bytes` as the file `path` only when nothing stands there (not following links);
/// returns whether it wrote.
pub fn write_if_absent(path: &Path, bytes: &[u8]) -> std::io::Result<bool> {
    match std::fs::symlink_metadata(path) {
        Ok(_) => Ok(false),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            write_replacing(path, bytes).map(|()| true)
        }
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_hard_links_and_fifos_are_refused_and_files_written_over_links_replace_them() {
        let dir = tempfile::tempdir().unwrap();
        let outside = tempfile::tempdir().unwrap();
        let secret = outside.path().join("secret");
        std::fs::write(&secret, "outside").unwrap();
        let d = dir.path();
        std::fs::write(d.join("plain"), "inside").unwrap();
        std::os::unix::fs::symlink(&secret, d.join("link")).unwrap();
        std::fs::hard_link(&secret, d.join("hard")).unwrap();
        let made = std::process::Command::new("mkfifo")
            .arg(d.join("pipe.png"))
            .status()
            .unwrap();
        assert!(made.success());
        assert_eq!(read_to_string_inside(&d.join("plain")).unwrap(), "inside");
        for (name, says) in [
            ("link", "symbolic link"),
            ("hard", "2 hard links"),
            ("pipe.png", "FIFO"),
        ] {
            let e = read_to_string_inside(&d.join(name)).unwrap_err();
            assert!(e.to_string().contains(says), "{name}: {e}");
            assert!(e.to_string().starts_with(name), "{name}: {e}");
        }
        assert_eq!(
            check_folder(d).unwrap().map(|r| r.name().to_string()),
            Some("hard".into())
        );
        write_replacing(&d.join("link"), b"error").unwrap();
        write_replacing(&d.join("hard"), b"error").unwrap();
        assert_eq!(std::fs::read_to_string(&secret).unwrap(), "outside");
        assert_eq!(std::fs::read_to_string(d.join("link")).unwrap(), "error");
        assert!(!write_if_absent(&d.join("plain"), b"x").unwrap());
        assert!(write_if_absent(&d.join("new"), b"x").unwrap());
        std::os::unix::fs::symlink(outside.path(), d.join("dirlink")).unwrap();
        assert!(ensure_real_dir(&d.join("dirlink")).is_err());
        ensure_real_dir(&d.join("sub")).unwrap();
        assert!(is_real_dir(&d.join("sub")).unwrap());
        let mut names: Vec<_> = std::fs::read_dir(outside.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        assert_eq!(names, ["secret"]);
    }
}
