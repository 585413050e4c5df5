//! The watched directory stays inside (issue 79, item 2): a symlinked epoch folder, a symlinked
//! site folder, an `epoch.json` or a station image linked to a file outside, a hard link to a file
//! outside and a FIFO named like an image. Nothing outside is read or written (the outside
//! folder's listing, sizes, modification times and its files' access times, set in the past
//! before the scan, are the same after it); the refusal is reported inside: `error.txt` of the
//! folder in `.failed/` names the item and why, a note in the site's `.failed/` names a linked
//! epoch folder, and a linked site folder (no folder inside can hold a note) is logged.

use crate::support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use cliffwatch::watch::{scan, scan_once, WatchOptions};
use support::server::TestServer;
use support::watch::{small_scene, write_epoch};

/// Copies the files of `from` into a new folder `to`.
fn copy_folder(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for f in std::fs::read_dir(from).unwrap().flatten() {
        std::fs::copy(f.path(), to.join(f.file_name())).unwrap();
    }
}

/// The first station image (`.png`) of `folder`, by name.
fn first_png(folder: &Path) -> PathBuf {
    let mut pngs: Vec<PathBuf> = std::fs::read_dir(folder)
        .unwrap()
        .flatten()
        .map(|f| f.path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    pngs.sort();
    pngs.remove(0)
}

/// Sets the access time of every file under `dir` to 1 January 2020 (`touch -a`), so that any
/// read of one moves it (`relatime` updates an access time older than the modification time).
fn age_access_times(dir: &Path) {
    for (path, _) in snapshot(dir) {
        let file = dir.join(&path);
        if std::fs::symlink_metadata(&file).unwrap().is_file() {
            let ok = std::process::Command::new("touch")
                .args(["-a", "-d", "2020-01-01 00:00:00"])
                .arg(&file)
                .status()
                .unwrap();
            assert!(ok.success(), "touch -a {}", file.display());
        }
    }
}

/// What is under `dir` (not following links), per relative path: kind, size, modification time
/// and, for files, access time (a folder's access time moves when the snapshot lists it).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (String, u64, SystemTime, Option<SystemTime>)> {
    let mut out = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let m = e.metadata().unwrap();
            let rel = e.path().strip_prefix(dir).unwrap().to_path_buf();
            if m.is_dir() {
                todo.push(e.path());
            }
            let atime = m.is_file().then(|| m.accessed().unwrap());
            let kind = format!("{:?}", m.file_type());
            out.insert(rel, (kind, m.len(), m.modified().unwrap(), atime));
        }
    }
    out
}

/// A log sink the test reads back.
#[derive(Clone, Default)]
struct Logs(Arc<Mutex<Vec<u8>>>);

impl std::io::Write for Logs {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for Logs {
    type Writer = Logs;
    fn make_writer(&'a self) -> Logs {
        self.clone()
    }
}

/// Rows of `epochs` of `site`.
async fn epochs(server: &TestServer, site: &str) -> i64 {
    sqlx::query_scalar("SELECT COUNT(*) FROM epochs WHERE site_id = ?")
        .bind(site)
        .fetch_one(server.store.reader())
        .await
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn links_hard_links_and_fifos_are_refused_and_nothing_outside_is_touched() {
    let server = TestServer::start(|_| {}).await;
    let watch = tempfile::tempdir().unwrap();
    let outside = tempfile::tempdir().unwrap();
    let template = tempfile::tempdir().unwrap();
    let (e1, _) = write_epoch(
        template.path(),
        &small_scene(),
        "e1",
        "2026-11-20T09:00:00Z",
        true,
        1,
    );
    let image = first_png(&e1)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    let (w, o) = (watch.path(), outside.path());
    for site in [
        "eplink", "sitelink", "json", "image", "hard", "fifo", "plain",
    ] {
        server.create_site(site).await;
    }
    // a symlinked epoch folder in a real site folder
    copy_folder(&e1, &o.join("eplink-e1"));
    std::fs::create_dir_all(w.join("eplink")).unwrap();
    std::os::unix::fs::symlink(o.join("eplink-e1"), w.join("eplink/e1")).unwrap();
    // a symlinked site folder holding a ready epoch
    copy_folder(&e1, &o.join("sitelink/e1"));
    std::os::unix::fs::symlink(o.join("sitelink"), w.join("sitelink")).unwrap();
    // epoch.json linked to a file outside
    copy_folder(&e1, &w.join("json/e1"));
    std::fs::rename(w.join("json/e1/epoch.json"), o.join("epoch.json")).unwrap();
    std::os::unix::fs::symlink(o.join("epoch.json"), w.join("json/e1/epoch.json")).unwrap();
    // a station image linked to a file outside
    copy_folder(&e1, &w.join("image/e1"));
    std::fs::rename(w.join("image/e1").join(&image), o.join("image.png")).unwrap();
    std::os::unix::fs::symlink(o.join("image.png"), w.join("image/e1").join(&image)).unwrap();
    // a station image hard-linked to a file outside
    copy_folder(&e1, &w.join("hard/e1"));
    std::fs::rename(w.join("hard/e1").join(&image), o.join("hard.png")).unwrap();
    std::fs::hard_link(o.join("hard.png"), w.join("hard/e1").join(&image)).unwrap();
    // a FIFO named like a station image (a read would block the watcher)
    copy_folder(&e1, &w.join("fifo/e1"));
    std::fs::remove_file(w.join("fifo/e1").join(&image)).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(w.join("fifo/e1").join(&image))
        .status()
        .unwrap();
    assert!(made.success());
    // the same folder with no link: taken, so the refusals above are the links' doing
    copy_folder(&e1, &w.join("plain/e1"));

    age_access_times(o);
    let before = snapshot(o);
    assert!(before.values().all(|(_, _, _, a)| a.is_none_or(
        |a| a < SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_600_000_000)
    )));
    let refused: Vec<PathBuf> = scan(w).refused.into_iter().map(|r| r.path).collect();
    assert_eq!(refused, [w.join("eplink/e1"), w.join("sitelink")]);

    let logs = Logs::default();
    let subscriber = tracing_subscriber::fmt()
        .with_writer(logs.clone())
        .with_ansi(false)
        .finish();
    let guard = tracing::subscriber::set_default(subscriber);
    let opts = WatchOptions::new(w.to_path_buf());
    let taken = tokio::time::timeout(
        std::time::Duration::from_secs(120),
        scan_once(&server.store, &opts),
    )
    .await
    .expect("the scan ends (no FIFO blocks it)");
    drop(guard);
    let logged = String::from_utf8(logs.0.lock().unwrap().clone()).unwrap();

    // nothing outside read or written
    assert_eq!(snapshot(o), before, "the outside folder changed");
    // what was refused is reported inside, or logged
    assert_eq!(taken.len(), 5, "{taken:?}");
    for (site, item, why) in [
        ("json", "epoch.json", "symbolic link"),
        ("image", image.as_str(), "symbolic link"),
        ("hard", image.as_str(), "2 hard links"),
        ("fifo", image.as_str(), "FIFO"),
    ] {
        let failed = w.join(site).join(".failed/e1");
        let err = std::fs::read_to_string(failed.join("error.txt"))
            .unwrap_or_else(|e| panic!("{site}: no error.txt in .failed ({e})"));
        eprintln!("{site}: {}", err.trim());
        assert!(err.contains(&format!("{item} ")), "{site}: {err}");
        assert!(err.contains(why), "{site}: {err}");
        assert_eq!(epochs(&server, site).await, 0, "{site}");
    }
    let note = std::fs::read_to_string(w.join("eplink/.failed/e1.refused.txt")).unwrap();
    eprintln!("eplink: {}", note.trim());
    assert!(
        note.starts_with("e1 was not taken: e1 is a symbolic link"),
        "{note}"
    );
    assert!(
        std::fs::symlink_metadata(w.join("eplink/e1"))
            .unwrap()
            .is_symlink(),
        "the link stays where it is"
    );
    assert!(logged.contains("entry refused, not followed"), "{logged}");
    let site_line = logged
        .lines()
        .find(|l| l.contains(&w.join("sitelink").display().to_string()))
        .unwrap_or_else(|| panic!("the linked site folder is not logged: {logged}"));
    assert!(
        site_line.contains("sitelink is a symbolic link"),
        "{site_line}"
    );
    for site in ["eplink", "sitelink"] {
        assert_eq!(epochs(&server, site).await, 0, "{site}");
    }
    assert!(w.join("plain/.done/e1").is_dir(), "{taken:?}");
    assert_eq!(epochs(&server, "plain").await, 1);

    // a second scan writes no second note and still touches nothing outside
    let again = scan_once(&server.store, &opts).await;
    assert!(again.is_empty(), "{again:?}");
    assert_eq!(snapshot(o), before, "the outside folder changed");
    server.stop().await;
}
