//! Retry policy: exponential backoff with "equal jitter" (delay uniform in [d/2, d] with
//! d = min(cap, base·2^attempt)), `Retry-After` honoured as a floor (capped), a limit on attempts.

use std::time::Duration;

use chrono::{DateTime, Utc};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// How deliveries are retried.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RetryPolicy {
    /// Delay before the first retry, seconds (before jitter).
    pub base_seconds: f64,
    /// Largest backoff delay, seconds.
    pub max_delay_seconds: f64,
    /// Attempts in total (first delivery included) before giving up.
    pub max_attempts: u32,
    /// Largest `Retry-After` honoured, seconds (longer values are capped).
    pub max_retry_after_seconds: f64,
}

impl Default for RetryPolicy {
    fn default() -> Self {
        RetryPolicy {
            base_seconds: 5.0,
            max_delay_seconds: 3600.0,
            // at least 45 h of retries (at most ~90 h) before a message is given up: a receiver
            // down over a weekend night still gets every alarm
            max_attempts: 100,
            max_retry_after_seconds: 86_400.0,
        }
    }
}

/// Largest delay a policy may name, seconds (a year).
pub const MAX_POLICY_SECONDS: f64 = 365.0 * 86_400.0;

impl RetryPolicy {
    /// Checks the policy: delays finite, from 0 to a year, and at least one attempt; the
    /// message names the option at fault.
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [
            ("base_seconds", self.base_seconds),
            ("max_delay_seconds", self.max_delay_seconds),
            ("max_retry_after_seconds", self.max_retry_after_seconds),
        ] {
            if !(0.0..=MAX_POLICY_SECONDS).contains(&v) {
                return Err(format!(
                    "webhook_retry.{name} {v}: 0 to {MAX_POLICY_SECONDS} seconds"
                ));
            }
        }
        if self.max_attempts == 0 {
            return Err("webhook_retry.max_attempts: at least 1".into());
        }
        Ok(())
    }

    /// Backoff ceiling d = min(cap, base·2^attempt) in seconds for retry number `attempt` (0 = first retry).
    pub fn ceiling_seconds(&self, attempt: u32) -> f64 {
        (self.base_seconds * 2f64.powi(attempt.min(60) as i32))
            .min(self.max_delay_seconds)
            .max(0.0)
    }
}

/// Backoff delay of retry number `attempt` (0 = the first retry): uniform in [d/2, d].
pub fn backoff_delay<R: Rng + ?Sized>(policy: &RetryPolicy, attempt: u32, rng: &mut R) -> Duration {
    let d = policy.ceiling_seconds(attempt);
    let s = if d > 0.0 {
        rng.gen_range(0.5 * d..=d)
    } else {
        0.0
    };
    Duration::try_from_secs_f64(s).unwrap_or(Duration::ZERO)
}

/// When to retry after `attempts_made` failed attempts (≥ 1): `None` when the limit is reached. A server's
/// `Retry-After` (capped at `max_retry_after_seconds`) lengthens the backoff but never shortens it: a
/// receiver answering `Retry-After: 0` or `1` on every attempt would otherwise use up all
/// `max_attempts` within minutes and the message would be given up.
pub fn next_retry<R: Rng + ?Sized>(
    policy: &RetryPolicy,
    attempts_made: u32,
    retry_after: Option<Duration>,
    rng: &mut R,
) -> Option<Duration> {
    if attempts_made >= policy.max_attempts {
        return None;
    }
    let backoff = backoff_delay(policy, attempts_made.saturating_sub(1), rng);
    Some(match retry_after {
        Some(ra) => ra
            .min(
                Duration::try_from_secs_f64(policy.max_retry_after_seconds)
                    .unwrap_or(Duration::ZERO),
            )
            .max(backoff),
        None => backoff,
    })
}

/// Parses a `Retry-After` header: delay-seconds or an HTTP-date (relative to `now`; past dates give 0).
pub fn parse_retry_after(value: &str, now: DateTime<Utc>) -> Option<Duration> {
    let v = value.trim();
    if let Ok(s) = v.parse::<u64>() {
        return Some(Duration::from_secs(s));
    }
    let t = DateTime::parse_from_rfc2822(v).ok()?.to_utc();
    Some((t - now).to_std().unwrap_or(Duration::ZERO))
}
