//! The dashboard in a real browser and over HTTP, and the CAP feed.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules.

#[path = "../dashboard_support/mod.rs"]
mod dashboard_support;
#[path = "../plot_support/mod.rs"]
mod plot_support;
#[path = "../watch_support/mod.rs"]
mod watch_support;

mod alert_list;
mod block_page;
mod browser;
mod cap_feed;
mod headline;
mod pages;
mod plots;
mod security;
mod sessions;
