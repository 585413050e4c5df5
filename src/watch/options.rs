//! Options of the watcher: where, how often, and the detection and identification options.

use std::path::PathBuf;
use std::time::Duration;

use cliffwatch_core::detect::first_epoch::FirstEpochOptions;
use cliffwatch_core::detect::identify::IdentifyOptions;
use cliffwatch_core::detect::DetectOptions;

use crate::service::ingest::EpochLimits;

/// Options of the watcher.
#[derive(Debug, Clone)]
pub struct WatchOptions {
    /// The watched directory.
    pub dir: PathBuf,
    /// Period of the rescan.
    pub rescan: Duration,
    /// How long a ready folder's entries must stay the same before it is taken (the files of a
    /// copy that wrote `READY` first are still arriving); zero: at once.
    pub settle: Duration,
    /// Detection options.
    pub detect: DetectOptions,
    /// Identification options (a station from its previous orientation, or alone from its seeds).
    pub identify: IdentifyOptions,
    /// Multi-view identification options (stations of a first epoch, from their seeds).
    pub first_epoch: FirstEpochOptions,
    /// The largest epoch taken (as for uploads).
    pub limits: EpochLimits,
    /// Where people reach the dashboard (the configuration's `public_url`), for the links in
    /// the bodies of the alert events an epoch writes; `None`: no links.
    pub public_url: Option<String>,
}

impl WatchOptions {
    /// Defaults for `dir`: rescan every 30 s, take a folder once it has not changed for 2 s, no
    /// public URL.
    pub fn new(dir: PathBuf) -> Self {
        Self {
            dir,
            rescan: Duration::from_secs(30),
            settle: Duration::from_secs(2),
            detect: DetectOptions::default(),
            identify: IdentifyOptions::default(),
            first_epoch: FirstEpochOptions::default(),
            limits: EpochLimits::default(),
            public_url: None,
        }
    }
}
