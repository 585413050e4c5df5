-- Indexes for reads that scanned whole tables as the history grows:
-- - an endpoint's deliveries: GET /api/v1/webhooks counts each endpoint's pending and failed
--   deliveries and reads its last error, and the worker looks for an endpoint's due deliveries
--   (store::webhooks::list, store::outbox::claim_due); the index on (state, next_attempt_at)
--   serves neither by endpoint;
-- - alerts by their last change: the CAP feed lists the newest first (store::alerts::ever_public).
CREATE INDEX webhook_deliveries_by_endpoint ON webhook_deliveries (webhook_id, state, next_attempt_at);
CREATE INDEX alerts_by_update ON alerts (updated_at, id);
