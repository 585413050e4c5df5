-- Indexes that serve the alert lists from their cursor on, newest first (store::alerts::list):
-- GET /api/v1/alerts with no filter, a site, a state or both, and the site page. The old
-- alerts_by_time (raised_at) left the id of the order to a sort of every earlier alert, and
-- alerts_by_site (site_id, state) a sort of all of a site's alerts.
DROP INDEX alerts_by_time;
CREATE INDEX alerts_by_time ON alerts (raised_at, id);
DROP INDEX alerts_by_site;
CREATE INDEX alerts_by_site ON alerts (site_id, state, raised_at, id);
CREATE INDEX alerts_by_site_time ON alerts (site_id, raised_at, id);
CREATE INDEX alerts_by_state ON alerts (state, raised_at, id);
