//! A cancelled adjustment stops with `AdjustError::Cancelled` and no result; one cancelled from
//! another thread while it runs stops within a moment; one never cancelled gives the same
//! report as without a handle.

use std::time::{Duration, Instant};

use cliffwatch_core::photogrammetry::{adjust, AdjustError, AdjustOptions, Cancel};
use cliffwatch_sim::scenes::{long_range, LongRangeParams};

fn options(cancel: Cancel) -> AdjustOptions {
    AdjustOptions {
        cancel,
        ..AdjustOptions::default()
    }
}

#[test]
fn a_cancelled_or_expired_handle_stops_the_adjustment_and_says_which() {
    let (epoch, _) = long_range(&LongRangeParams {
        seed: 7,
        ..LongRangeParams::default()
    })
    .unwrap();
    let cancelled = Cancel::new();
    cancelled.cancel();
    match adjust(&epoch, &options(cancelled)) {
        Err(AdjustError::Cancelled { deadline }) => assert!(!deadline),
        other => panic!(
            "expected Cancelled, got {:?}",
            other.map(|a| a.report.converged)
        ),
    }
    let expired = Cancel::new().child(Some(Instant::now()));
    let e = adjust(&epoch, &options(expired)).unwrap_err();
    assert!(
        matches!(e, AdjustError::Cancelled { deadline: true }),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "the adjustment ran out of its compute budget"
    );

    // A handle never cancelled changes nothing.
    let plain = adjust(&epoch, &AdjustOptions::default()).unwrap();
    let with_handle = adjust(&epoch, &options(Cancel::new())).unwrap();
    assert_eq!(plain.report, with_handle.report);
}

#[test]
fn a_cancellation_from_another_thread_ends_a_running_adjustment_quickly() {
    // A large network, so that the adjustment runs well past the moment of the cancellation.
    let params = LongRangeParams {
        seed: 3,
        n_points: 3_000,
        ..LongRangeParams::default()
    };
    let (epoch, _) = long_range(&params).unwrap();
    let alone = Instant::now();
    adjust(&epoch, &AdjustOptions::default()).expect("adjusts");
    let full = alone.elapsed();
    let cancel = Cancel::new();
    let remote = cancel.clone();
    let after = full / 4;
    let canceller = std::thread::spawn(move || {
        std::thread::sleep(after);
        remote.cancel();
        Instant::now()
    });
    let result = adjust(&epoch, &options(cancel));
    let ended = Instant::now();
    let cancelled_at = canceller.join().unwrap();
    assert!(
        matches!(result, Err(AdjustError::Cancelled { deadline: false })),
        "{:?}",
        result.map(|a| a.report.converged)
    );
    let lag = ended.saturating_duration_since(cancelled_at);
    println!("full adjustment {full:?}; cancelled at {after:?}, ended {lag:?} later");
    assert!(
        lag < Duration::from_millis(500).max(full / 10),
        "ended {lag:?} after the cancellation (full run {full:?})"
    );
}
