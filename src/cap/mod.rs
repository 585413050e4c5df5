//! The public-warning feed: each warning- or alarm-level movement alert ([`PUBLIC_RULES`]; datum
//! and system alerts stay internal) as an OASIS Common Alerting
//! Protocol 1.2 message ([`message`]), and an Atom feed of them ([`feed`]), for the systems
//! through which authorities re-issue warnings. Pure, with input types of its own
//! ([`Subject`], [`Change`], [`SiteArea`]): the shell ([`crate::api::cap`]) reads the alert,
//! its recorded changes and its site, maps them, and serves what these functions write.
//!
//! An alert is one CAP thread: the first change that makes it public (raised at, or escalated
//! to, `warning` or `alarm`) is an `Alert` message, each later change of its public level an
//! `Update`, and its resolution or fall back to `watch` a `Cancel` ([`message::steps`]). Every
//! message has its own identifier (`<alert id>.<n>`) and references the earlier ones.

pub(crate) mod area;
pub(crate) mod feed;
pub(crate) mod message;
pub(crate) mod xml;

pub use area::{Circle, SiteArea};
pub use feed::{atom_feed, FeedEntry};
pub use message::{
    cap_message, headline, identifier, is_public_rule, steps, CapContext, CapStep, Change, MsgType,
    Snapshot, Subject, PUBLIC_RULES,
};
