//! One file per subcommand: argument types (clap) and the function that runs it.

pub mod adjust;
pub mod backup;
pub mod migrate_store;
pub mod serve;
pub mod simulate;
