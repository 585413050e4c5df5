-- The alerts an epoch raised (its summary: POST and GET of an epoch) by index; alerts_by_site
-- made SQLite read every alert of the site.
CREATE INDEX alerts_by_epoch ON alerts (site_id, epoch_id);
