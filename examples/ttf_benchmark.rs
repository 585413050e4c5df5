//! The time-to-failure benchmark on realistic kinematics ([`cliffwatch::simulate::kinematics`]):
//! cliffwatch's alarm against a plain inverse-velocity baseline on the same series. Prints the
//! table of `docs/accuracy.md`.
//!
//! `cargo run --release --example ttf_benchmark [-- SEEDS [FIRST]]` (default 40 seeds per kind
//! from 0: 200 series).

use cliffwatch::simulate::ttf_benchmark::{run_all, table};

fn main() {
    let mut args = std::env::args().skip(1);
    let seeds: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(40);
    let first: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let started = std::time::Instant::now();
    let outcomes = run_all(first, seeds);
    if std::env::var_os("TTF_VERBOSE").is_some() {
        for o in &outcomes {
            println!("{o:?}");
        }
    }
    println!(
        "{} series ({seeds} seeds per kind from {first}), {:.1} s\n",
        outcomes.len(),
        started.elapsed().as_secs_f64()
    );
    print!("{}", table(&outcomes));
}
