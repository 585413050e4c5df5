-- cliffwatch schema, version 6: the body format of each webhook endpoint, and the body of one
-- delivery when it is not the outbox's contract body. Portable SQL as in version 1.

-- 'standard' (the contract body), 'alertmanager_webhook' (Alertmanager's webhook body, version 4)
-- or 'alertmanager_api_v2' (Alertmanager's POST /api/v2/alerts body); existing endpoints keep the
-- contract body
ALTER TABLE webhooks ADD COLUMN format TEXT NOT NULL DEFAULT 'standard'
    CHECK (format IN ('standard', 'alertmanager_webhook', 'alertmanager_api_v2'));

-- the body sent to this endpoint, rendered in its format when the event was written (so every
-- retry sends the same bytes); NULL: the contract body of the outbox row
ALTER TABLE webhook_deliveries ADD COLUMN payload TEXT;
