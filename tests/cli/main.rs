//! The daemon's binary as a user runs it from the command line: `cliffwatch adjust` and
//! `cliffwatch detect` (their numerical code is tested in the core's crate).

#[path = "../support/mod.rs"]
mod support;

mod adjust;
mod detect;
mod plan;
mod readme;
