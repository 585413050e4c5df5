//! Administering a site over the years: its settings edited with a JSON merge patch (checked as
//! a new site is), a block group deleted, and every change of a site's settings recorded in its
//! audit trail (who, when, from where, before and after) in the transaction that makes it. A
//! change of what the series or the rules depend on recomputes the site at once, and the events
//! of the alerts it decides name the change.

use serde_json::Value;

use crate::store::audit::{self, AuditEntry};
use crate::store::sites::{self, NewSite, Site};
use crate::store::{epochs, groups, Connection, Store, StoreError};

use super::alert_outcome::count_raised;
use super::recompute::{recompute_site, RecomputeCause};
use super::sites::validate_site;
use super::ServiceError;

/// Who makes a change, and from where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Actor {
    /// `token 1a2b3c4d5e6f7a8b (admin)`, `anonymous`, `configuration file`.
    pub who: String,
    /// `api`, `page` or `configuration`.
    pub source: &'static str,
}

/// Records one change of `site` in its audit trail, inside the change's transaction.
pub(crate) async fn record(
    tx: &mut Connection,
    site: &str,
    actor: &Actor,
    action: &str,
    target: &str,
    before: Option<&Value>,
    after: Option<&Value>,
) -> Result<String, StoreError> {
    let at = crate::store::timestamp(crate::store::clock(&mut *tx).await?);
    let id = format!("{at}-{:08x}", rand::random::<u32>());
    audit::insert(
        &mut *tx,
        &AuditEntry {
            id: id.clone(),
            site_id: site.to_string(),
            at,
            actor: actor.who.clone(),
            source: actor.source.to_string(),
            action: action.to_string(),
            target: target.to_string(),
            value_before: before.map(Value::to_string),
            value_after: after.map(Value::to_string),
        },
    )
    .await?;
    Ok(id)
}

/// RFC 7396: merges `patch` into `target` (an object member set to null is removed).
pub fn merge_patch(target: &mut Value, patch: &Value) {
    let Value::Object(p) = patch else {
        *target = patch.clone();
        return;
    };
    if !target.is_object() {
        *target = Value::Object(Default::default());
    }
    let t = target.as_object_mut().expect("an object");
    for (k, v) in p {
        if v.is_null() {
            t.remove(k);
        } else {
            merge_patch(t.entry(k.clone()).or_insert(Value::Null), v);
        }
    }
}

/// The stored site as the create form holds it (every setting it has, defaults written out).
pub fn as_new_site(s: &Site) -> NewSite {
    NewSite {
        id: s.id.clone(),
        name: Some(s.name.clone()),
        model: Some(s.model),
        schedule_hours: s.schedule_hours,
        confidence: Some(s.confidence),
        alert_rules: Some(s.alert_rules.clone()),
        reference_epochs: Some(s.reference_epochs),
        process_noise: s.process_noise,
        time_zone: s.time_zone.clone(),
        area: s.area.clone(),
        response_text: s.response_text.clone(),
        contacts: (!s.contacts.is_empty()).then(|| s.contacts.clone()),
        image_weights: Some(s.image_weights),
        frame: Some(s.frame),
        apriori_sigma: Some(s.apriori_sigma),
        detection: Some(s.detection),
    }
}

/// Whether the series or the alert rules depend on what changed between `b` and `a`.
pub fn analysis_changed(b: &Site, a: &Site) -> bool {
    (
        b.reference_epochs,
        b.process_noise,
        b.confidence,
        &b.alert_rules,
    ) != (
        a.reference_epochs,
        a.process_noise,
        a.confidence,
        &a.alert_rules,
    )
}

/// Applies the JSON merge patch `patch` to the settings of `site` (every member of the create
/// form but `id`; null removes an optional one), with the checks of a new site, in one
/// transaction with its audit row; a change of the rules or the analysis settings recomputes
/// the site and re-evaluates its alerts at once (the event bodies link under `public_url`, the
/// configuration's). Returns the stored site.
pub async fn update_site(
    store: &Store,
    site: &str,
    patch: &Value,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<Site, ServiceError> {
    let invalid = |m: String| ServiceError::InvalidSite(m);
    if !patch.is_object() {
        return Err(invalid(
            "the body: a JSON object of the settings to change (RFC 7396 merge patch)".into(),
        ));
    }
    let mut tx = store.begin_write_site(site).await?;
    let before = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    super::sites::ensure_in_service(&before)?;
    let before_json = serde_json::to_value(as_new_site(&before)).map_err(StoreError::from)?;
    if patch.get("id").is_some_and(|id| id.as_str() != Some(site)) {
        return Err(invalid(format!(
            "id: a site's id cannot change (it names the site in every URL and epoch); \
             create a new site '{}' instead",
            cliffwatch_core::contract::truncate_for_message(
                &patch["id"]
                    .as_str()
                    .map_or(patch["id"].to_string(), str::to_string)
            )
        )));
    }
    let mut merged = before_json.clone();
    merge_patch(&mut merged, patch);
    merged["id"] = Value::String(site.to_string());
    let new: NewSite =
        serde_json::from_value(merged.clone()).map_err(|e| invalid(e.to_string()))?;
    validate_site(&new)?;
    if new.model.unwrap_or_default() != before.model && epochs::count(&mut *tx, site).await? > 0 {
        return Err(invalid(format!(
            "model: the site's epochs were adjusted with the {} model; a site keeps its model \
             once it has epochs",
            before.model.as_str()
        )));
    }
    sites::upsert(&mut tx, &new).await?;
    let after = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    let after_json = serde_json::to_value(as_new_site(&after)).map_err(StoreError::from)?;
    if after_json == before_json {
        return Ok(after);
    }
    let (b, a) = changed_members(&before_json, &after_json);
    let id = record(
        &mut tx,
        site,
        actor,
        "site.update",
        &format!("site {site}"),
        Some(&b),
        Some(&a),
    )
    .await?;
    let mut raised = 0;
    if analysis_changed(&before, &after) {
        let cause = RecomputeCause::Edit(format!(
            "the site's settings were changed by {} (audit {id})",
            actor.who
        ));
        raised = recompute_site(&mut tx, site, &cause, public_url).await?;
    }
    tx.commit().await.map_err(StoreError::from)?;
    count_raised(raised);
    Ok(after)
}

/// The members of `before` and `after` that differ, each side as an object of them (a member
/// one side lacks is null on it).
fn changed_members(before: &Value, after: &Value) -> (Value, Value) {
    let (mut b, mut a) = (serde_json::Map::new(), serde_json::Map::new());
    let empty = serde_json::Map::new();
    let bo = before.as_object().unwrap_or(&empty);
    let ao = after.as_object().unwrap_or(&empty);
    for k in bo.keys().chain(ao.keys()) {
        let (x, y) = (bo.get(k), ao.get(k));
        if x != y && !b.contains_key(k) {
            b.insert(k.clone(), x.cloned().unwrap_or(Value::Null));
            a.insert(k.clone(), y.cloned().unwrap_or(Value::Null));
        }
    }
    (Value::Object(b), Value::Object(a))
}

/// Deletes block group `group` of `site` (its points stay, as points outside any block) and
/// recomputes the site, with its audit row (the event bodies link under `public_url`).
/// [`ServiceError::UnknownGroup`] when there is none.
pub async fn delete_group(
    store: &Store,
    site: &str,
    group: &str,
    actor: &Actor,
    public_url: Option<&str>,
) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let Some(stored) = sites::get(&mut *tx, site).await? else {
        return Err(ServiceError::UnknownSite(site.to_string()));
    };
    super::sites::ensure_in_service(&stored)?;
    let Some(before) = groups::get(&mut *tx, site, group).await? else {
        return Err(ServiceError::UnknownGroup(group.to_string()));
    };
    groups::delete(&mut *tx, site, group).await?;
    let before = serde_json::to_value(&before).map_err(StoreError::from)?;
    let target = format!("group {group}");
    let id = record(
        &mut tx,
        site,
        actor,
        "group.delete",
        &target,
        Some(&before),
        None,
    )
    .await?;
    let cause = RecomputeCause::Edit(format!(
        "block group {group} was deleted by {} (audit {id})",
        actor.who
    ));
    let raised = recompute_site(&mut tx, site, &cause, public_url).await?;
    tx.commit().await.map_err(StoreError::from)?;
    count_raised(raised);
    Ok(())
}

/// The changes of `site`, newest first, after the cursor `after`, at most `limit`.
pub async fn audit_trail(
    store: &Store,
    site: &str,
    after: Option<(&str, &str)>,
    limit: i64,
) -> Result<Vec<AuditEntry>, ServiceError> {
    if sites::get(store.reader(), site).await?.is_none() {
        return Err(ServiceError::UnknownSite(site.to_string()));
    }
    Ok(audit::list(store.reader(), site, after, limit).await?)
}
