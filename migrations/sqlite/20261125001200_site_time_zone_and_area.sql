-- Issue 13: a site's time zone (the dashboard shows times in UTC and in it) and its warning area
-- (JSON: description, polygon or circle in WGS 84) for the CAP messages.
ALTER TABLE sites ADD COLUMN time_zone TEXT;
ALTER TABLE sites ADD COLUMN area TEXT;

-- The CAP feed and the point page read an alert's recorded changes.
CREATE INDEX webhook_outbox_by_alert ON webhook_outbox (alert_id);
