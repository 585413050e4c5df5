//! The helpers the core's test binaries share, one copy of each: a binary takes them all with
//! `#[path = "../support/mod.rs"] mod support;` and uses what it needs (the rest is dead code to
//! it, hence the `allow`). No server helper: the core's tests link the core and the simulator only.
//!
//! - `adjust`, `analysis`: the shared epochs and checks of the adjustment and analysis tests;
//! - `identify`: the long-range scene with its cameras, orientations and seeds;
//! - `dbat`: DBAT's real photographs and PhotoModeler's marks and points;
//! - `bad_images`: image files that are broken in each way a decoder meets.
//!
//! `identify`, `dbat` and `bad_images` serve the daemon's watched-directory tests too, which take
//! these files by `#[path]` (one copy of each).
#![allow(dead_code)]

/// The folder that holds the shared reference data, `../shared` beside the repository, as a
/// string literal (this crate's manifest lies two folders below the repository's root).
macro_rules! shared_dir {
    () => {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")
    };
}

pub mod adjust;
pub mod analysis;
pub mod bad_images;
pub mod dbat;
pub mod identify;
