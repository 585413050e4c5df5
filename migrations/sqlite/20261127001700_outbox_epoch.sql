-- The epoch whose analysis caused each alert event (NULL for events of no epoch), so that an
-- epoch's summary lists the alerts that epoch raised or escalated, not every alert still active.
-- Events written before this column take the epoch of their contract body.
ALTER TABLE webhook_outbox ADD COLUMN epoch_id BIGINT;
UPDATE webhook_outbox SET epoch_id = json_extract(payload, '$.data.epoch')
WHERE json_valid(payload);
CREATE INDEX webhook_outbox_by_epoch ON webhook_outbox (epoch_id);
