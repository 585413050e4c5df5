//! The dashboard in a real browser and over HTTP, and the CAP feed.
//!
//! One test binary per area (each binary links the whole crate once); the files are its modules,
//! and `tests/support/` holds the helpers every binary shares.

#[path = "../support/mod.rs"]
mod support;

mod alert_list;
mod apriori_sigma;
mod block_page;
mod browser;
mod cap_feed;
mod headline;
mod pages;
mod phone;
mod plan_labels;
mod plots;
mod report;
mod security;
mod sensitivity;
mod sessions;
mod site_edit;
mod site_frame;
