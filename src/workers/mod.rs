//! The daemon's background loops, each run under the shutdown signal until it stops: they call
//! the use cases of [`crate::service`] and the store, and nothing calls them but the daemon.
//!
//! - [`webhook_delivery`]: the outbox worker (signed webhooks, retries).
//! - [`alertmanager_resend`]: every open alert posted to Alertmanager again each period.
//! - [`overdue`]: the campaign schedule check.
//! - [`retention`]: finished webhook deliveries and old epochs' observations deleted after
//!   their retention periods.
//! - [`watch_retention`]: the watched directory's taken folders deleted after theirs.

pub mod alertmanager_resend;
pub(crate) mod overdue;
pub mod retention;
pub mod watch_retention;
pub(crate) mod webhook_delivery;
