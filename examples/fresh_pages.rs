//! What memory touched for the first time costs on this machine, the floor under a fresh process's
//! run (`docs/performance.md`, `cliffwatch adjust` as a whole process):
//! `cargo run --release --example fresh_pages -- MIB RUNS` writes one byte into each 4 KiB page of
//! RUNS new blocks of MIB MiB (default 12 and 5) and prints the time per page of the first pass
//! (a page fault each: the kernel finds and zeroes a page) and of a second pass over the same pages.

use std::time::Instant;

const PAGE: usize = 4096;

fn main() {
    let mut args = std::env::args().skip(1);
    let mib: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(12);
    let runs: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(5);
    let len = mib << 20;
    // All blocks are kept until the end, so each run's pages are new to the process.
    let mut blocks: Vec<Vec<u8>> = Vec::with_capacity(runs);
    for _ in 0..runs {
        // Zeroed and this large, the block comes straight from the kernel, not yet backed.
        let mut block = vec![0u8; len];
        let first = touch(&mut block, 1);
        let second = touch(&mut block, 2);
        let pages = (len / PAGE) as f64;
        println!(
            "{mib} MiB: first touch {:.2} ms ({:.2} µs/page), second pass {:.3} ms",
            first * 1e3,
            first * 1e6 / pages,
            second * 1e3
        );
        blocks.push(block);
    }
    std::hint::black_box(&blocks);
}

/// Writes `value` into the first byte of every page of `block`; seconds taken.
fn touch(block: &mut [u8], value: u8) -> f64 {
    let start = Instant::now();
    for i in (0..block.len()).step_by(PAGE) {
        // Volatile, so the writes are neither merged nor dropped.
        unsafe { std::ptr::write_volatile(&mut block[i], value) };
    }
    start.elapsed().as_secs_f64()
}
