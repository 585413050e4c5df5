-- The alerts an epoch raised (its summary: POST and GET of an epoch) by index, as on SQLite.
CREATE INDEX alerts_by_epoch ON alerts (site_id, epoch_id);
