//! Changes of a site's settings that the derived series depend on: the reference epoch, the
//! declared block groups and the points' roles, groups and directions. Each change and the
//! recompute it causes commit in one transaction.

use crate::store::points::{self, Point, PointSettings};
use crate::store::{epochs, groups, sites, Store, StoreError};
use cliffwatch_core::analysis::{GroupConfig, PointRole};

use serde_json::json;

use super::alert_outcome::count_raised;
use super::recompute::{recompute_site, RecomputeCause};
use super::site_admin::{record, Actor};
use super::ServiceError;

/// Sets the reference epoch of `site` (`None`: back to the earliest epoch) and recomputes its
/// displacements and alerts (the event bodies link under `public_url`, the configuration's).
pub async fn set_reference(
    store: &Store,
    site: &str,
    epoch: Option<i64>,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let Some(stored) = sites::get(&mut *tx, site).await? else {
        return Err(ServiceError::UnknownSite(site.to_string()));
    };
    super::sites::ensure_in_service(&stored)?;
    if let Some(e) = epoch {
        if epochs::observed_at_raw(&mut *tx, site, e).await?.is_none() {
            return Err(ServiceError::UnknownEpoch {
                site: site.to_string(),
                epoch: e,
            });
        }
    }
    sites::set_reference(&mut *tx, site, epoch).await?;
    if stored.reference_epoch != epoch {
        let (b, a) = (
            json!({"epoch": stored.reference_epoch}),
            json!({"epoch": epoch}),
        );
        record(
            &mut tx,
            site,
            actor,
            "reference.set",
            &format!("site {site}"),
            Some(&b),
            Some(&a),
        )
        .await?;
    }
    let cause = RecomputeCause::Reference(epoch, actor.who.clone());
    let raised = recompute_site(&mut tx, site, &cause, public_url).await?;
    tx.commit().await.map_err(StoreError::from)?;
    count_raised(raised);
    Ok(())
}

/// Declares (or replaces) a block group of `site` and recomputes the site's series and alerts
/// (the event bodies link under `public_url`).
pub async fn declare_group(
    store: &Store,
    site: &str,
    group: &GroupConfig,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let Some(stored) = sites::get(&mut *tx, site).await? else {
        return Err(ServiceError::UnknownSite(site.to_string()));
    };
    super::sites::ensure_in_service(&stored)?;
    let before = groups::get(&mut *tx, site, &group.name).await?;
    groups::put(&mut tx, site, group).await?;
    if before.as_ref() != Some(group) {
        let b = before
            .map(serde_json::to_value)
            .transpose()
            .map_err(StoreError::from)?;
        let a = serde_json::to_value(group).map_err(StoreError::from)?;
        let target = format!("group {}", group.name);
        record(
            &mut tx,
            site,
            actor,
            "group.put",
            &target,
            b.as_ref(),
            Some(&a),
        )
        .await?;
    }
    let cause = RecomputeCause::Group(group.name.clone());
    let raised = recompute_site(&mut tx, site, &cause, public_url).await?;
    tx.commit().await.map_err(StoreError::from)?;
    count_raised(raised);
    Ok(())
}

/// Most points one bulk change may set.
pub const MAX_POINTS_PER_CHANGE: usize = 10_000;

/// Sets a point's role, group or direction of interest ([`set_points`] with one point).
pub async fn set_point(
    store: &Store,
    site: &str,
    point: &str,
    settings: &PointSettings,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<Point, ServiceError> {
    let changes = [(point.to_string(), settings.clone())];
    let mut done = set_points(store, site, &changes, actor, public_url).await?;
    done.pop().ok_or_else(|| {
        StoreError::Corrupt(format!("point '{point}' of site '{site}' vanished")).into()
    })
}

/// Sets the role, group or direction of interest of each of `changes` in one transaction
/// (creating a point when new: before the site's first epoch, or declared `planned`; otherwise
/// a name no epoch observed is refused as [`ServiceError::UnmeasuredPoint`] and nothing is
/// stored), each change in the audit trail, and, when that changed anything and the site has
/// epochs, recomputes the site once: the stable points hold the datum, the group decides the
/// block, the direction the value along it, so a series derived before the change would
/// otherwise jump at the next epoch (the event bodies link under `public_url`). Returns the
/// stored points in the order given.
pub async fn set_points(
    store: &Store,
    site: &str,
    changes: &[(String, PointSettings)],
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<Vec<Point>, ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let Some(stored) = sites::get(&mut *tx, site).await? else {
        return Err(ServiceError::UnknownSite(site.to_string()));
    };
    super::sites::ensure_in_service(&stored)?;
    let has_epochs = epochs::count(&mut *tx, site).await? > 0;
    let mut stored = Vec::with_capacity(changes.len());
    let mut changed = vec![];
    for (point, settings) in changes {
        let before = points::get(&mut *tx, site, point).await?;
        // Every point an epoch observed has a row; before the first epoch every point is planned.
        if before.is_none() && !settings.planned && has_epochs {
            return Err(ServiceError::UnmeasuredPoint {
                site: site.to_string(),
                point: point.to_string(),
            });
        }
        points::upsert(&mut *tx, site, point, settings).await?;
        let after = points::get(&mut *tx, site, point).await?.ok_or_else(|| {
            StoreError::Corrupt(format!("point '{point}' of site '{site}' vanished"))
        })?;
        // A point without settings is a monitored one outside any group.
        let was = before.clone().unwrap_or_else(|| Point {
            name: after.name.clone(),
            role: PointRole::Monitored,
            group: None,
            direction: None,
        });
        if was != after {
            let b = before
                .as_ref()
                .map(serde_json::to_value)
                .transpose()
                .map_err(StoreError::from)?;
            let a = serde_json::to_value(&after).map_err(StoreError::from)?;
            let target = format!("point {point}");
            record(
                &mut tx,
                site,
                actor,
                "point.set",
                &target,
                b.as_ref(),
                Some(&a),
            )
            .await?;
            changed.push(point.clone());
        }
        stored.push(after);
    }
    let mut raised = 0;
    if !changed.is_empty() && has_epochs {
        let cause = match changed.as_slice() {
            [one] => RecomputeCause::Point(one.clone()),
            many => RecomputeCause::Point(format!("{} and {} more", many[0], many.len() - 1)),
        };
        raised = recompute_site(&mut tx, site, &cause, public_url).await?;
    }
    tx.commit().await.map_err(StoreError::from)?;
    count_raised(raised);
    Ok(stored)
}
