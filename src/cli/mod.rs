//! One file per subcommand: argument types (clap) and the function that runs it; `heap` sets how
//! malloc grows its heaps for the one-shot `adjust`.

pub mod adjust;
pub mod backup;
pub mod detect;
pub mod heap;
pub mod migrate_store;
pub mod overlay;
pub mod plan;
pub mod serve;
pub mod simulate;
