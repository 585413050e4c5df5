//! An Atom feed (RFC 4287) of CAP messages: one entry per alert, pointing at its latest message.

use chrono::{DateTime, Utc};

use super::xml::{atom_time, escape};

/// One entry: an alert's latest CAP message.
#[derive(Debug, Clone)]
pub struct FeedEntry {
    /// The entry's IRI, the same for every message of the alert (e.g. `urn:uuid:…`).
    pub id: String,
    /// The message's headline.
    pub title: String,
    /// One line: msgType, level, site and subject.
    pub summary: String,
    /// When the latest message was sent.
    pub updated: DateTime<Utc>,
    /// Where the CAP message is served (`…/api/v1/cap/alerts/<id>.xml`).
    pub href: String,
    /// The public level of the latest message (`warning` or `alarm`), an Atom category.
    pub level: cliffwatch_core::analysis::AlertLevel,
}

/// The feed document. `id` is the feed's IRI, `self_href` where it is served; `updated` is
/// the newest entry's time, or `now` when there is none.
pub fn atom_feed(
    id: &str,
    title: &str,
    self_href: &str,
    entries: &[FeedEntry],
    now: DateTime<Utc>,
) -> String {
    let updated = entries.iter().map(|e| e.updated).max().unwrap_or(now);
    let mut x = String::with_capacity(1024 + 600 * entries.len());
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    x.push_str("<feed xmlns=\"http://www.w3.org/2005/Atom\">\n");
    x.push_str(&format!("  <id>{}</id>\n", escape(id)));
    x.push_str(&format!("  <title>{}</title>\n", escape(title)));
    x.push_str(&format!("  <updated>{}</updated>\n", atom_time(updated)));
    x.push_str("  <author><name>cliffwatch</name></author>\n");
    x.push_str(&format!(
        "  <link rel=\"self\" type=\"application/atom+xml\" href=\"{}\"/>\n",
        escape(self_href)
    ));
    x.push_str("  <generator>cliffwatch</generator>\n");
    for e in entries {
        x.push_str("  <entry>\n");
        x.push_str(&format!("    <id>{}</id>\n", escape(&e.id)));
        x.push_str(&format!("    <title>{}</title>\n", escape(&e.title)));
        x.push_str(&format!(
            "    <updated>{}</updated>\n",
            atom_time(e.updated)
        ));
        x.push_str(&format!("    <summary>{}</summary>\n", escape(&e.summary)));
        x.push_str(&format!("    <category term=\"{}\"/>\n", e.level));
        x.push_str(&format!(
            "    <link rel=\"alternate\" type=\"application/cap+xml\" href=\"{}\"/>\n",
            escape(&e.href)
        ));
        x.push_str("  </entry>\n");
    }
    x.push_str("</feed>\n");
    x
}
