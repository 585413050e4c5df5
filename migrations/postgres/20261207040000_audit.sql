-- Issue 77: every change of a site's settings, who made it, from where, and what it was before
-- and after (JSON), listed newest first per site. The id is the change's time and a random
-- suffix (copies between stores keep it; no sequence to advance).
CREATE TABLE audit (
    id           TEXT COLLATE "C" NOT NULL PRIMARY KEY,
    site_id      TEXT COLLATE "C" NOT NULL,
    at           TEXT COLLATE "C" NOT NULL,
    actor        TEXT COLLATE "C" NOT NULL,
    source       TEXT COLLATE "C" NOT NULL,
    action       TEXT COLLATE "C" NOT NULL,
    target       TEXT COLLATE "C" NOT NULL,
    value_before TEXT COLLATE "C",
    value_after  TEXT COLLATE "C"
);
CREATE INDEX audit_site_at ON audit (site_id, at, id);
