-- Issue 61: the epoch that raised each alert, and its observation time (the row's epoch_id and
-- observed_at follow the latest evaluation), so that the alert list says on which epoch an alert
-- was raised. Alerts written before take the epoch of their `alert.raised` event.
ALTER TABLE alerts ADD COLUMN raised_epoch_id BIGINT;
ALTER TABLE alerts ADD COLUMN raised_observed_at TEXT COLLATE "C";
UPDATE alerts SET raised_epoch_id = (SELECT o.epoch_id FROM webhook_outbox o
    WHERE o.alert_id = alerts.id AND o.event_type = 'alert.raised' ORDER BY o.created_at LIMIT 1);
UPDATE alerts SET raised_observed_at = (SELECT e.observed_at FROM epochs e
    WHERE e.site_id = alerts.site_id AND e.id = alerts.raised_epoch_id);
