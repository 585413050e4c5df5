//! Incidents: what staff act on. An incident is a declared block with its member points, or a
//! point outside any block, or the site itself, with every open alert of every rule on it; one
//! block makes one incident however many points and rules alert. Incidents are ordered by
//! urgency: the earliest "failure likely before" first, then the highest level, then the oldest.
//! Acknowledging an incident acknowledges its open alerts in one transaction, each recorded with
//! who and the comment.
//!
//! [`group`] and [`block_of`] are pure; [`list`] and [`acknowledge`] read and write the store.

use std::collections::HashMap;

use chrono::{DateTime, Utc};
use serde::Serialize;

use super::acknowledge::{acknowledge_in, checked_acknowledgement};
use super::forecast::{failure_time, ttf, FailureTime};
pub use super::incident_subject::{block_of, blocks_of_site, subject_for, subject_of, Subject};
use super::ServiceError;
use crate::store::alerts::Alert;
use crate::store::{self, alerts, block_motions, displacements, groups, points, Store, StoreError};
use cliffwatch_core::analysis::{AlertLevel, AlertStatus};

/// Open alerts read per site to gather incidents (the store lists them newest first).
pub const ALERTS_READ: i64 = 1000;

/// One row: a subject and its alerts (most severe first).
#[derive(Debug)]
pub struct SubjectAlerts<'a> {
    /// Whose.
    pub subject: Subject,
    /// Its alerts, highest level first, then by metric, then by point.
    pub alerts: Vec<&'a Alert>,
}

impl SubjectAlerts<'_> {
    /// The highest level of its alerts.
    pub fn worst(&self) -> AlertLevel {
        self.alerts
            .iter()
            .map(|a| a.level)
            .max()
            .unwrap_or_default()
    }

    /// The metrics behind it, each once with its highest level, the highest first.
    pub fn metrics(&self) -> Vec<(&str, AlertLevel)> {
        let mut out: Vec<(&str, AlertLevel)> = Vec::new();
        for a in &self.alerts {
            match out.iter_mut().find(|(r, _)| *r == a.rule) {
                Some((_, l)) => *l = (*l).max(a.level),
                None => out.push((a.rule.as_str(), a.level)),
            }
        }
        out.sort_by_key(|m| std::cmp::Reverse(m.1));
        out
    }

    /// The first raised of its alerts: the one whose raising epoch was observed first (then
    /// the one processed first).
    pub fn first_raised(&self) -> Option<&Alert> {
        self.alerts.iter().copied().min_by(|a, b| {
            let at = |x: &Alert| x.raised_observed_at.clone().unwrap_or(x.raised_at.clone());
            (at(a), &a.raised_at).cmp(&(at(b), &b.raised_at))
        })
    }
}

/// Groups `alerts` into one row per subject: rows by worst level (highest first), then by the
/// newest first raising, then by subject; `block_of` names the declared block of each point in
/// one.
pub fn group<'a>(
    alerts: &'a [Alert],
    block_of: &HashMap<String, String>,
) -> Vec<SubjectAlerts<'a>> {
    let mut rows: Vec<SubjectAlerts<'a>> = Vec::new();
    for a in alerts {
        let s = subject_of(a, block_of);
        match rows.iter_mut().find(|r| r.subject == s) {
            Some(r) => r.alerts.push(a),
            None => rows.push(SubjectAlerts {
                subject: s,
                alerts: vec![a],
            }),
        }
    }
    for r in &mut rows {
        r.alerts.sort_by(|a, b| {
            (b.level, &a.rule, &a.group, &a.point).cmp(&(a.level, &b.rule, &b.group, &b.point))
        });
    }
    let raised = |r: &SubjectAlerts<'_>| {
        r.first_raised()
            .map(|a| a.raised_observed_at.clone().unwrap_or(a.raised_at.clone()))
            .unwrap_or_default()
    };
    rows.sort_by(|a, b| {
        (b.worst(), raised(b), &a.subject).cmp(&(a.worst(), raised(a), &b.subject))
    });
    rows
}

/// An incident's forecast: the block's own when it has one, else the earliest bound among its
/// points (named as such), counted from the epoch of the row it comes from.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct IncidentForecast {
    /// Whose forecast it is: `block B1` or `point T119`.
    pub from: String,
    /// Time to failure, h, counted from `observed_at`.
    pub hours: f64,
    /// Its 1σ, h, when known.
    pub sigma_hours: Option<f64>,
    /// Observation time of the epoch it counts from (RFC 3339).
    pub observed_at: String,
    /// Failure is likely before this time (RFC 3339): the one-sided upper bound at
    /// `confidence`, the bound the time-to-failure rules read.
    pub likely_before: String,
    /// The confidence of `likely_before` (one-sided).
    pub confidence: f64,
    /// The forecast failure time (RFC 3339).
    pub expected_at: String,
}

/// One incident as the API lists it.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct Incident {
    /// Its id within the site: `block:B1`, `point:T203` or `site`.
    pub id: String,
    /// `block`, `point` or `site`.
    pub kind: String,
    /// The block's or point's name (`null` for the site).
    pub subject: Option<String>,
    /// The highest level of its alerts.
    pub level: AlertLevel,
    /// `open` while one of its alerts is open, else `acknowledged`.
    pub state: AlertStatus,
    /// The points its alerts concern, in natural order.
    pub points: Vec<String>,
    /// Metrics of its alerts, each once, the highest level first.
    pub rules: Vec<String>,
    /// Its alerts' ids, the highest level first.
    pub alert_ids: Vec<String>,
    /// Who acknowledged its alerts (each name once).
    pub acknowledged_by: Vec<String>,
    /// When its first alert was raised (processing time, RFC 3339).
    pub raised_at: String,
    /// Observation time of the epoch that raised its first alert (RFC 3339).
    pub raised_observed_at: Option<String>,
    /// Its forecast failure time, when a forecast is stated.
    pub forecast: Option<IncidentForecast>,
    /// Its page on the dashboard (path): the block's, the point's or the site's.
    pub page: String,
}

/// "2026-06-21T00:27:00Z" from seconds since 1970.
fn rfc3339(t: f64) -> String {
    DateTime::<Utc>::from_timestamp(t.round() as i64, 0)
        .map(store::timestamp)
        .unwrap_or_default()
}

impl IncidentForecast {
    /// The stated forecast of row `d` of `from`.
    fn of(from: String, d: &displacements::Displacement, f: FailureTime) -> Option<Self> {
        let (hours, sigma_hours) = ttf(d)?;
        Some(IncidentForecast {
            from,
            hours,
            sigma_hours: sigma_hours.filter(|s| s.is_finite()),
            observed_at: d.observed_at.clone(),
            likely_before: rfc3339(f.likely_before),
            confidence: cliffwatch_core::analysis::failure::BOUND_CONFIDENCE,
            expected_at: rfc3339(f.at),
        })
    }
}

/// The forecast of a subject: a block's own (its latest motion row), else the earliest bound of
/// its points' latest rows; a point's latest row. `latest`: the site's latest row per point.
async fn forecast_of(
    store: &Store,
    site: &str,
    subject: &Subject,
    members: &[String],
    latest: &[displacements::Displacement],
) -> Result<Option<IncidentForecast>, StoreError> {
    if let Subject::Block(b) = subject {
        let own = block_motions::latest(store.reader(), site, b).await?;
        if let Some(f) = own.as_ref().and_then(|d| {
            failure_time(d).and_then(|f| IncidentForecast::of(format!("block {b}"), d, f))
        }) {
            return Ok(Some(f));
        }
    }
    let wanted: Vec<&str> = match subject {
        Subject::Point(p) => vec![p.as_str()],
        Subject::Block(_) => members.iter().map(String::as_str).collect(),
        Subject::Site => vec![],
    };
    Ok(latest
        .iter()
        .filter(|d| wanted.contains(&d.point.as_str()))
        .filter_map(|d| failure_time(d).map(|f| (f.likely_before, d, f)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .and_then(|(_, d, f)| IncidentForecast::of(format!("point {}", d.point), d, f)))
}

/// The incidents of `site` (its open and acknowledged alerts), most urgent first.
pub async fn list(store: &Store, site: &str) -> Result<Vec<Incident>, ServiceError> {
    let db = store.reader();
    let open: Vec<Alert> = alerts::list_active(db, site, ALERTS_READ)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .collect();
    let blocks = groups::list(db, site).await?;
    let pts = points::list(db, site, None, i64::MAX).await?;
    let members = block_of(&blocks, &pts);
    let latest = displacements::latest(&mut *store.read().await?, site).await?;
    let mut out = vec![];
    for r in group(&open, &members) {
        let mut points: Vec<String> = r
            .alerts
            .iter()
            .flat_map(|a| a.point.iter().cloned().chain(a.points.iter().cloned()))
            .collect();
        if let Subject::Block(b) = &r.subject {
            points.extend(
                members
                    .iter()
                    .filter(|(_, g)| *g == b)
                    .map(|(p, _)| p.clone()),
            );
        }
        points.sort_by(|a, b| crate::natural_order::natural_cmp(a, b));
        points.dedup();
        let forecast = forecast_of(store, site, &r.subject, &points, &latest).await?;
        out.push(incident(site, &r, points, forecast));
    }
    out.sort_by(|a, b| {
        urgency(a)
            .partial_cmp(&urgency(b))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    Ok(out)
}

/// The sort key of urgency: the earliest bound first (none last), the highest level, the oldest.
fn urgency(i: &Incident) -> (String, std::cmp::Reverse<AlertLevel>, String) {
    (
        i.forecast
            .as_ref()
            .map_or("~".to_string(), |f| f.likely_before.clone()),
        std::cmp::Reverse(i.level),
        i.raised_observed_at
            .clone()
            .unwrap_or_else(|| i.raised_at.clone()),
    )
}

/// The API's view of row `r` of `site`.
fn incident(
    site: &str,
    r: &SubjectAlerts<'_>,
    points: Vec<String>,
    forecast: Option<IncidentForecast>,
) -> Incident {
    let page = r.subject.page(site);
    let (kind, subject) = match &r.subject {
        Subject::Block(b) => ("block", Some(b.clone())),
        Subject::Point(p) => ("point", Some(p.clone())),
        Subject::Site => ("site", None),
    };
    let mut acknowledged_by: Vec<String> = vec![];
    for a in &r.alerts {
        if let Some(by) = &a.acknowledged_by {
            if !acknowledged_by.contains(by) {
                acknowledged_by.push(by.clone());
            }
        }
    }
    let first = r.first_raised();
    Incident {
        id: r.subject.key(),
        kind: kind.into(),
        subject,
        level: r.worst(),
        state: if r.alerts.iter().any(|a| a.state == AlertStatus::Open) {
            AlertStatus::Open
        } else {
            AlertStatus::Acknowledged
        },
        points,
        rules: r
            .metrics()
            .into_iter()
            .map(|(m, _)| m.to_string())
            .collect(),
        alert_ids: r.alerts.iter().map(|a| a.id.clone()).collect(),
        acknowledged_by,
        raised_at: first.map(|a| a.raised_at.clone()).unwrap_or_default(),
        raised_observed_at: first.and_then(|a| a.raised_observed_at.clone()),
        forecast,
        page,
    }
}

/// Acknowledges incident `id` of `site` for `by` with an optional comment: every open alert of
/// it, in one write transaction, as [`super::acknowledge::acknowledge`] does one (same limits on
/// `by` and `comment`). [`ServiceError::UnknownIncident`] when the site has no such incident;
/// [`ServiceError::AlreadyAcknowledged`] when every alert of it is acknowledged already. Returns
/// the incident after. The events' bodies link under `public_url` (the configuration's).
pub async fn acknowledge(
    store: &Store,
    site: &str,
    id: &str,
    by: &str,
    comment: Option<&str>,
    public_url: Option<&str>,
) -> Result<Incident, ServiceError> {
    let (by, comment) = checked_acknowledgement(by, comment)?;
    let mut tx = store.begin_write_site(site).await?;
    let open: Vec<Alert> = alerts::list_active(&mut *tx, site, ALERTS_READ)
        .await?
        .into_iter()
        .map(|(_, a)| a)
        .collect();
    let blocks = groups::list(&mut *tx, site).await?;
    let pts = points::list(&mut *tx, site, None, i64::MAX).await?;
    let rows = group(&open, &block_of(&blocks, &pts));
    let Some(row) = rows.iter().find(|r| r.subject.key() == id) else {
        return Err(ServiceError::UnknownIncident(id.to_string()));
    };
    let pending: Vec<String> = row
        .alerts
        .iter()
        .filter(|a| a.state == AlertStatus::Open)
        .map(|a| a.id.clone())
        .collect();
    if pending.is_empty() {
        let who = row
            .alerts
            .iter()
            .find_map(|a| a.acknowledged_by.clone())
            .unwrap_or_default();
        return Err(ServiceError::AlreadyAcknowledged {
            id: id.to_string(),
            by: who,
        });
    }
    let now = store::clock(&mut tx).await?;
    for alert in &pending {
        acknowledge_in(&mut tx, alert, by, comment, now, public_url).await?;
    }
    tx.commit().await.map_err(StoreError::from)?;
    list(store, site)
        .await?
        .into_iter()
        .find(|i| i.id == id)
        .ok_or_else(|| ServiceError::UnknownIncident(id.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alert(point: Option<&str>, group: Option<&str>, rule: &str, level: &str, at: &str) -> Alert {
        let mut a = Alert::default();
        a.point = point.map(str::to_string);
        a.group = group.map(str::to_string);
        a.rule = rule.into();
        a.level = level.parse().unwrap();
        a.raised_at = "2026-12-01T20:43:00Z".into();
        a.raised_observed_at = Some(at.into());
        a
    }

    /// A block's own alerts and its members' gather in one row, with the worst level, the
    /// metrics each once and the earliest raising; a point outside blocks keeps its own row.
    #[test]
    fn a_block_and_its_members_make_one_row() {
        let alerts = vec![
            alert(
                Some("T10"),
                None,
                "displacement_mm",
                "watch",
                "2026-11-03T09:00:00Z",
            ),
            alert(
                Some("T11"),
                None,
                "velocity_mm_per_day",
                "warning",
                "2026-11-04T09:00:00Z",
            ),
            alert(
                None,
                Some("B1"),
                "displacement_mm",
                "alarm",
                "2026-11-05T09:00:00Z",
            ),
            alert(
                Some("T20"),
                None,
                "displacement_mm",
                "warning",
                "2026-11-02T09:00:00Z",
            ),
            alert(
                None,
                None,
                "campaign_overdue",
                "watch",
                "2026-11-06T09:00:00Z",
            ),
        ];
        let block_of: HashMap<String, String> = [("T10", "B1"), ("T11", "B1")]
            .map(|(p, b)| (p.into(), b.into()))
            .into();
        let rows = group(&alerts, &block_of);
        let subjects: Vec<Subject> = rows.iter().map(|r| r.subject.clone()).collect();
        assert_eq!(
            subjects,
            [
                Subject::Block("B1".into()),
                Subject::Point("T20".into()),
                Subject::Site
            ]
        );
        let b1 = &rows[0];
        assert_eq!(b1.alerts.len(), 3);
        assert_eq!(b1.worst(), AlertLevel::Alarm);
        assert_eq!(
            b1.metrics(),
            [
                ("displacement_mm", AlertLevel::Alarm),
                ("velocity_mm_per_day", AlertLevel::Warning)
            ]
        );
        assert_eq!(
            b1.first_raised()
                .and_then(|a| a.raised_observed_at.as_deref()),
            Some("2026-11-03T09:00:00Z")
        );
    }
}
