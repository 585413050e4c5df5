-- One site's CAP feed lists that site's alerts by their last change, newest first
-- (store::alerts::ever_public with a site): alerts_by_update (updated_at, id) left it to scan
-- every site's alerts, alerts_by_site a sort of all of the site's.
CREATE INDEX alerts_by_site_update ON alerts (site_id, updated_at, id);
