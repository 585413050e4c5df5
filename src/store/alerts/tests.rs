//! The alert rows' store functions against a real SQLite store.

use super::*;
use crate::store::{Store, StoreOptions};

/// Point names are case-sensitive: an alert on `A1` (as its point or in its points) is not
/// one of point `a1`'s, though SQLite's `LIKE` ignores case.
#[tokio::test]
async fn the_alerts_of_a_point_match_its_name_exactly() {
    let (_dir, store) = empty_store().await;
    let mut tx = store.begin_write().await.unwrap();
    sqlx::query("INSERT INTO sites (id, name, created_at) VALUES ('s', 's', '2026-01-01')")
        .execute(&mut *tx)
        .await
        .unwrap();
    for (id, epoch, point, points) in [
        ("a", 1, None, r#"["A1","B2"]"#),
        ("b", 2, Some("A1"), "[]"),
        ("c", 3, None, r#"["a1"]"#),
    ] {
        sqlx::query(
            "INSERT INTO alerts (id, site_id, point, points, level, rule, epoch_id, message, \
             state, raised_at, updated_at) VALUES ($1, 's', $2, $3, 'watch', 'r', $4, 'm', \
             'open', '2026-01-01', '2026-01-01')",
        )
        .bind(id)
        .bind(point)
        .bind(points)
        .bind(epoch)
        .execute(&mut *tx)
        .await
        .unwrap();
        sqlx::query(
            "INSERT INTO webhook_outbox (id, event_type, alert_id, level, payload, created_at) \
             VALUES ($1, 'alert.raised', $1, 'watch', '{}', '2026-01-01')",
        )
        .bind(id)
        .execute(&mut *tx)
        .await
        .unwrap();
    }
    tx.commit().await.unwrap();
    let mut upper = epochs_of_point(store.reader(), "s", "A1").await.unwrap();
    upper.sort_unstable();
    assert_eq!(upper, [1, 2]);
    assert_eq!(
        epochs_of_point(store.reader(), "s", "a1").await.unwrap(),
        [3]
    );
    let events = |p: &'static str| {
        let store = store.clone();
        async move {
            let mut ids: Vec<String> = events_of_point(store.reader(), "s", p)
                .await
                .unwrap()
                .into_iter()
                .map(|e| e.alert_id)
                .collect();
            ids.sort();
            ids
        }
    };
    assert_eq!(events("A1").await, ["a", "b"]);
    assert_eq!(events("a1").await, ["c"]);
    assert!(events("B").await.is_empty());
}

/// Every filter of the alert list pages through exactly the alerts a plain filter and sort
/// give, and reads an index from the cursor on: no scan of the table and no sort.
#[tokio::test]
async fn each_alert_filter_pages_in_order_through_its_own_index() {
    let (_dir, store) = empty_store().await;
    let mut tx = store.begin_write().await.unwrap();
    for site in ["s1", "s2"] {
        sqlx::query("INSERT INTO sites (id, name, created_at) VALUES ($1, $1, '2026-01-01')")
            .bind(site)
            .execute(&mut *tx)
            .await
            .unwrap();
    }
    // 24 alerts over two sites and three states; pairs share their raised_at, so the id
    // decides the order within a pair.
    let mut all = Vec::new();
    for k in 0..24 {
        let site = ["s1", "s2"][k % 2];
        let state = ["open", "acknowledged", "resolved"][k % 3];
        let raised = format!("2026-01-01T00:{:02}:00Z", k / 2);
        let id = format!("{site}:p{k:02}");
        sqlx::query(
            "INSERT INTO alerts (id, site_id, point, points, level, rule, epoch_id, message, \
             state, raised_at, updated_at) VALUES ($1, $2, NULL, '[]', 'watch', 'r', 1, 'm', \
             $3, $4, $4)",
        )
        .bind(&id)
        .bind(site)
        .bind(state)
        .bind(&raised)
        .execute(&mut *tx)
        .await
        .unwrap();
        all.push((raised, id, site, state));
    }
    tx.commit().await.unwrap();
    all.sort_by(|a, b| (&b.0, &b.1).cmp(&(&a.0, &a.1)));
    let states = [
        None,
        Some(AlertStatus::Open),
        Some(AlertStatus::Acknowledged),
        Some(AlertStatus::Resolved),
    ];
    for site in [None, Some("s1"), Some("s2")] {
        for state in states {
            let expected: Vec<&str> = all
                .iter()
                .filter(|a| site.is_none_or(|s| a.2 == s))
                .filter(|a| state.is_none_or(|s| a.3 == s.as_str()))
                .map(|a| a.1.as_str())
                .collect();
            let mut got = Vec::new();
            let mut cursor: Option<(String, String)> = None;
            loop {
                let after = cursor.as_ref().map(|(t, id)| (t.as_str(), id.as_str()));
                let page = list(store.reader(), site, state, after, 3).await.unwrap();
                got.extend(page.iter().map(|(_, a)| a.id.clone()));
                match page.last() {
                    Some((raw, a)) if page.len() == 3 => cursor = Some((raw.clone(), a.id.clone())),
                    _ => break,
                }
            }
            assert_eq!(got, expected, "site {site:?}, state {state:?}");

            let text_params = usize::from(site.is_some()) + usize::from(state.is_some()) + 2;
            let plan = explain(
                &store,
                &list_sql(site.is_some(), state.is_some()),
                text_params,
            )
            .await;
            assert!(
                plan.iter()
                    .any(|line| line.starts_with("SEARCH alerts USING INDEX"))
                    && !plan
                        .iter()
                        .any(|line| line.contains("SCAN") || line.contains("TEMP B-TREE")),
                "site {site:?}, state {state:?}: {plan:?}"
            );
        }
    }
}

/// The CAP feed reads its alerts newest first straight from an index: one site's from
/// `alerts_by_site_update`, all sites' from `alerts_by_update`; no sort of the alerts.
#[tokio::test]
async fn the_cap_feed_reads_alerts_in_index_order() {
    let (_dir, store) = empty_store().await;
    for (site, index, text_params) in [
        (
            true,
            "SEARCH alerts USING INDEX alerts_by_site_update (site_id=?)",
            1,
        ),
        (false, "SCAN alerts USING INDEX alerts_by_update", 0),
    ] {
        let plan = explain(&store, &ever_public_sql(site), text_params).await;
        assert!(
            plan.iter().any(|line| line == index)
                && !plan.iter().any(|line| line.contains("TEMP B-TREE")),
            "site {site}: {plan:?}"
        );
    }
}

/// An empty store in a temporary directory (kept while the directory lives).
async fn empty_store() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("t.db"), &StoreOptions::default())
        .await
        .unwrap();
    (dir, store)
}

/// The top level of SQLite's query plan of `sql` (`text_params` text parameters, then an
/// integer), one line per step: the per-alert subquery of [`COLUMNS`] is left out.
async fn explain(store: &Store, sql: &str, text_params: usize) -> Vec<String> {
    use sqlx::Row;
    let sql = format!("EXPLAIN QUERY PLAN {sql}");
    let mut query = sqlx::query(&sql);
    for _ in 0..text_params {
        query = query.bind("x");
    }
    let rows = query.bind(3_i64).fetch_all(store.reader()).await.unwrap();
    rows.iter()
        .filter(|r| r.get::<i64, _>(1) == 0)
        .map(|r| r.get::<String, _>(3))
        .collect()
}
