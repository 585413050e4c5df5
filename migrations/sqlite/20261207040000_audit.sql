-- Issue 77: every change of a site's settings, who made it, from where, and what it was before
-- and after (JSON), listed newest first per site. The id is the change's time and a random
-- suffix (copies between stores keep it; no sequence to advance).
CREATE TABLE audit (
    id           TEXT NOT NULL PRIMARY KEY,
    site_id      TEXT NOT NULL,
    at           TEXT NOT NULL,
    actor        TEXT NOT NULL,
    source       TEXT NOT NULL,
    action       TEXT NOT NULL,
    target       TEXT NOT NULL,
    value_before TEXT,
    value_after  TEXT
);
CREATE INDEX audit_site_at ON audit (site_id, at, id);
