//! Whose an alert is: the incident subject (a declared block with its points, a point outside
//! every block, or the site), its key and its dashboard page, from the site's declared blocks.
//! Apart from [`super::incidents`] so that writing alert events
//! ([`super::alert_outcome`]) can name the incident without depending on acknowledging.

use std::collections::HashMap;

use crate::store::alerts::Alert;
use crate::store::{self, groups, points, StoreError};
use cliffwatch_core::analysis::GroupConfig;

/// Whose alerts a row gathers.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Subject {
    /// A declared block: its own alerts and its member points'.
    Block(String),
    /// A point that is in no declared block.
    Point(String),
    /// The site's own alerts (reference, schedule, analysis).
    Site,
}

impl Subject {
    /// "block B1", "point T203", "the site": the subject in words.
    pub fn words(&self) -> String {
        match self {
            Subject::Block(b) => format!("block {b}"),
            Subject::Point(p) => format!("point {p}"),
            Subject::Site => "the site".into(),
        }
    }

    /// Its key in the page (`block:B1`, `point:T203`, `site`), for `data-subject`.
    pub fn key(&self) -> String {
        match self {
            Subject::Block(b) => format!("block:{b}"),
            Subject::Point(p) => format!("point:{p}"),
            Subject::Site => "site".into(),
        }
    }

    /// Its page on the dashboard under `site` (a path): the block's, the point's or the
    /// site's. The link webhooks and Alertmanager carry, and the incident's `page`.
    pub fn page(&self, site: &str) -> String {
        use crate::url_path::seg;
        match self {
            Subject::Block(b) => format!("/sites/{}/groups/{}", seg(site), seg(b)),
            Subject::Point(p) => format!("/sites/{}/points/{}", seg(site), seg(p)),
            Subject::Site => format!("/sites/{}", seg(site)),
        }
    }
}

/// The subject of alert `a`, given the declared block of each point in one (`block_of`).
pub fn subject_of(a: &Alert, block_of: &HashMap<String, String>) -> Subject {
    subject_for(a.group.as_deref(), a.point.as_deref(), block_of)
}

/// The subject of an alert on `group` (a block's own alert) or `point` (a point's), or on
/// neither (the site's), given the declared block of each point in one (`block_of`).
pub fn subject_for(
    group: Option<&str>,
    point: Option<&str>,
    block_of: &HashMap<String, String>,
) -> Subject {
    match (group, point) {
        (Some(g), _) => Subject::Block(g.to_string()),
        (None, Some(p)) => match block_of.get(p) {
            Some(b) => Subject::Block(b.clone()),
            None => Subject::Point(p.to_string()),
        },
        (None, None) => Subject::Site,
    }
}

/// The declared block of each point of `site` that is in one ([`block_of`] of its groups and
/// points), read on `conn`.
pub async fn blocks_of_site(
    conn: &mut store::Connection,
    site: &str,
) -> Result<HashMap<String, String>, StoreError> {
    let blocks = groups::list(&mut *conn, site).await?;
    if blocks.is_empty() {
        return Ok(HashMap::new());
    }
    let pts = points::list(&mut *conn, site, None, i64::MAX).await?;
    Ok(block_of(&blocks, &pts))
}

/// The declared block of each point in one: a block's listed points, or, when it lists none,
/// the points whose group names it.
pub fn block_of(blocks: &[GroupConfig], pts: &[points::Point]) -> HashMap<String, String> {
    let mut out = HashMap::new();
    for b in blocks {
        if b.points.is_empty() {
            for p in pts
                .iter()
                .filter(|p| p.group.as_deref() == Some(b.name.as_str()))
            {
                out.insert(p.name.clone(), b.name.clone());
            }
        }
        for p in &b.points {
            out.insert(p.clone(), b.name.clone());
        }
    }
    out
}
