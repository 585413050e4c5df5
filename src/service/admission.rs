//! Admission of uploads on one node: at most `slots` uploads are processed at once (each parses,
//! adjusts on the CPU and writes under the site's lock; the API takes the slot once the body has
//! arrived, so slow senders do not hold one); the others wait in arrival order for at most `wait`, then are turned away with a time to retry (HTTP 503 and
//! `Retry-After`). Without it, a burst of uploads shares the cores until every one of them runs
//! past the request time limit and nothing is stored; with it, the first ones finish at full
//! speed and the rest are told when to come back. A turned-away upload stores nothing.
//!
//! Each slot carries the upload's [`Cancel`]: its compute budget runs from the slot's taking, the
//! daemon cancels every one at the end of its shutdown grace, and the upload's use case cancels
//! its own when it is dropped (its client answered or gone), so an adjustment never outlives
//! the request that asked for it by more than one iteration.

use std::sync::Arc;
use std::time::{Duration, Instant};

use cliffwatch_core::photogrammetry::Cancel;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// The upload slots of a node. Cloning shares the slots.
#[derive(Debug, Clone)]
pub struct UploadGate {
    slots: Arc<Semaphore>,
    size: usize,
    wait: Duration,
    /// Cancels every upload's computation ([`UploadGate::stop_computing`]).
    computing: Cancel,
    /// How long one upload may compute once it holds its slot.
    budget: Duration,
}

/// An upload turned away: every slot stayed busy for the whole wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{slots} uploads are being processed and none finished within {waited_secs} s; retry in {retry_after_secs} s")]
pub struct Overloaded {
    /// The node's upload slots.
    pub slots: usize,
    /// How long the upload waited, seconds (rounded up).
    pub waited_secs: u64,
    /// When to retry, seconds (the `Retry-After` header).
    pub retry_after_secs: u64,
}

/// A held upload slot; the slot is free again when this is dropped.
#[derive(Debug)]
pub struct UploadSlot {
    _permit: OwnedSemaphorePermit,
    cancel: Cancel,
}

impl UploadSlot {
    /// The upload's cancellation: its compute budget, the daemon's shutdown, and its own.
    pub fn cancel(&self) -> &Cancel {
        &self.cancel
    }
}

/// Cancels its handle when dropped: held by a use case's future, it stops the computation the
/// future started on a blocking thread when the future is dropped before it ends (the client
/// answered by the request time limit, or gone).
#[derive(Debug)]
pub struct CancelOnDrop(pub Cancel);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.cancel();
    }
}

impl Drop for UploadSlot {
    fn drop(&mut self) {
        metrics::gauge!("cliffwatch_upload_slots_busy").decrement(1.0);
    }
}

impl UploadGate {
    /// `slots` uploads at once (0: [`UploadGate::default_slots`]), each waiting at most `wait`
    /// for a slot.
    pub fn new(slots: usize, wait: Duration) -> Self {
        let size = if slots == 0 {
            Self::default_slots()
        } else {
            slots
        };
        UploadGate {
            slots: Arc::new(Semaphore::new(size)),
            size,
            wait,
            computing: Cancel::new(),
            budget: Duration::from_secs(crate::config::DEFAULT_COMPUTE_BUDGET_SECS),
        }
    }

    /// The same gate with each upload's compute budget (from the slot's taking).
    pub fn with_budget(mut self, budget: Duration) -> Self {
        self.budget = budget;
        self
    }

    /// Cancels the computation of every upload, running or to come (the daemon's shutdown).
    pub fn stop_computing(&self) {
        self.computing.cancel();
    }

    /// Twice the cores this process may use (an upload also waits on the database, so the cores
    /// stay busy while some wait), at least 2.
    pub fn default_slots() -> usize {
        std::thread::available_parallelism()
            .map(|n| 2 * n.get())
            .unwrap_or(2)
            .max(2)
    }

    /// The number of slots.
    pub fn size(&self) -> usize {
        self.size
    }

    /// Takes a slot, waiting in arrival order for at most the gate's wait (a wait of zero takes
    /// a free slot or none).
    pub async fn enter(&self) -> Result<UploadSlot, Overloaded> {
        let permit = if self.wait.is_zero() {
            self.slots.clone().try_acquire_owned().ok()
        } else {
            tokio::time::timeout(self.wait, self.slots.clone().acquire_owned())
                .await
                .ok()
                .and_then(Result::ok)
        };
        match permit {
            Some(permit) => {
                metrics::gauge!("cliffwatch_upload_slots_busy").increment(1.0);
                Ok(UploadSlot {
                    _permit: permit,
                    cancel: self.computing.child(Some(Instant::now() + self.budget)),
                })
            }
            None => {
                let waited_secs = self.wait.as_secs_f64().ceil() as u64;
                Err(Overloaded {
                    slots: self.size,
                    waited_secs,
                    retry_after_secs: waited_secs.clamp(1, 60),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_full_gate_turns_away_after_its_wait_and_admits_in_order() {
        let gate = UploadGate::new(1, Duration::from_millis(50));
        assert_eq!(gate.size(), 1);
        let held = gate.enter().await.expect("a free slot");
        let started = std::time::Instant::now();
        let refused = gate.enter().await.expect_err("no slot while one is held");
        assert!(started.elapsed() >= Duration::from_millis(50));
        assert_eq!(refused.retry_after_secs, 1);
        assert_eq!(refused.slots, 1);
        // Two waiters: the first to arrive gets the slot first.
        let gate = UploadGate::new(1, Duration::from_secs(5));
        let order = Arc::new(std::sync::Mutex::new(Vec::new()));
        let held2 = gate.enter().await.unwrap();
        let mut tasks = Vec::new();
        for k in 0..2 {
            let (gate, order) = (gate.clone(), order.clone());
            tasks.push(tokio::spawn(async move {
                let slot = gate.enter().await.unwrap();
                order.lock().unwrap().push(k);
                tokio::time::sleep(Duration::from_millis(5)).await;
                drop(slot);
            }));
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        drop(held2);
        for t in tasks {
            t.await.unwrap();
        }
        assert_eq!(*order.lock().unwrap(), vec![0, 1]);
        drop(held);
    }

    #[tokio::test]
    async fn a_slot_carries_its_budget_and_the_gate_cancels_every_slot() {
        let gate = UploadGate::new(2, Duration::ZERO).with_budget(Duration::from_millis(50));
        let a = gate.enter().await.unwrap();
        assert!(!a.cancel().is_cancelled());
        tokio::time::sleep(Duration::from_millis(80)).await;
        assert!(a.cancel().is_cancelled() && a.cancel().deadline_passed());
        let gate = UploadGate::new(2, Duration::ZERO);
        let (b, c) = (gate.enter().await.unwrap(), gate.enter().await.unwrap());
        drop(CancelOnDrop(b.cancel().clone()));
        assert!(b.cancel().is_cancelled() && !c.cancel().is_cancelled());
        gate.stop_computing();
        assert!(c.cancel().is_cancelled() && !c.cancel().deadline_passed());
    }

    #[tokio::test]
    async fn a_zero_wait_takes_a_free_slot_or_none() {
        let gate = UploadGate::new(2, Duration::ZERO);
        let a = gate.enter().await.unwrap();
        let _b = gate.enter().await.unwrap();
        assert!(gate.enter().await.is_err());
        drop(a);
        assert!(gate.enter().await.is_ok());
        assert!(UploadGate::new(0, Duration::ZERO).size() >= 2);
    }
}
