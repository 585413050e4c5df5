//! Cancellation of an adjustment: a caller that no longer wants the result (its client went away,
//! its compute budget is spent, the daemon is stopping) says so, and the adjustment stops at its
//! next iteration with [`AdjustError::Cancelled`](crate::photogrammetry::AdjustError::Cancelled)
//! instead of running to the end. The adjustment only reads the flags and the clock.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Whether an adjustment is still wanted: any of its flags set, or its deadline passed, cancels
/// it. The default is never cancelled. Clones share the flags.
#[derive(Debug, Clone, Default)]
pub struct Cancel {
    /// The flags that cancel: this handle's own (the last) and those of the handles it was made
    /// from ([`Cancel::child`]).
    flags: Vec<Arc<AtomicBool>>,
    /// When the adjustment stops being wanted, if ever.
    deadline: Option<Instant>,
}

impl Cancel {
    /// A handle that is cancelled only by [`Cancel::cancel`].
    pub fn new() -> Cancel {
        Cancel {
            flags: vec![Arc::new(AtomicBool::new(false))],
            deadline: None,
        }
    }

    /// A handle cancelled by its own [`Cancel::cancel`], by this one's, or at `deadline` (the
    /// earlier of it and this one's deadline).
    pub fn child(&self, deadline: Option<Instant>) -> Cancel {
        let mut flags = self.flags.clone();
        flags.push(Arc::new(AtomicBool::new(false)));
        let deadline = match (self.deadline, deadline) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Cancel { flags, deadline }
    }

    /// Cancels this handle, its clones and the handles made from it.
    pub fn cancel(&self) {
        if let Some(own) = self.flags.last() {
            own.store(true, Ordering::Relaxed);
        }
    }

    /// Whether the adjustment is no longer wanted: a flag set, or the deadline passed.
    pub fn is_cancelled(&self) -> bool {
        self.flags.iter().any(|f| f.load(Ordering::Relaxed))
            || self.deadline.is_some_and(|d| Instant::now() >= d)
    }

    /// Whether the deadline (not a flag) is what cancelled it.
    pub fn deadline_passed(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_parent_cancels_its_children_and_not_the_reverse() {
        let parent = Cancel::new();
        let child = parent.child(None);
        let sibling = parent.child(None);
        assert!(!child.is_cancelled());
        child.cancel();
        assert!(child.is_cancelled() && !parent.is_cancelled() && !sibling.is_cancelled());
        parent.cancel();
        assert!(sibling.is_cancelled());
        assert!(!Cancel::default().is_cancelled());
    }

    #[test]
    fn a_deadline_cancels_once_passed() {
        let now = Instant::now();
        let late = Cancel::new().child(Some(now + Duration::from_secs(3600)));
        assert!(!late.is_cancelled() && !late.deadline_passed());
        let past = late.child(Some(now - Duration::from_millis(1)));
        assert!(past.is_cancelled() && past.deadline_passed());
        // the earlier deadline holds whichever handle gave it
        let child_of_past = past.child(Some(now + Duration::from_secs(10)));
        assert!(child_of_past.is_cancelled());
    }
}
