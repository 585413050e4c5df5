-- Issue 12: declared point groups (rigid blocks) and the site settings of the filtered analysis.
CREATE TABLE groups (
    site_id        TEXT NOT NULL REFERENCES sites (id),
    name           TEXT NOT NULL,
    kind           TEXT NOT NULL CHECK (kind IN ('block')),
    direction      TEXT,                      -- JSON [dx, dy, dz] or NULL
    points         TEXT NOT NULL DEFAULT '[]', -- JSON array of member points; [] = by the points' group
    process_noise  DOUBLE PRECISION,
    updated_at     TEXT NOT NULL,
    PRIMARY KEY (site_id, name)
);
-- The reference is the covariance-weighted mean of this many epochs from the reference epoch on.
ALTER TABLE sites ADD COLUMN reference_epochs BIGINT NOT NULL DEFAULT 1;
-- The Kalman filter's process noise of the site's points (NULL: the library default).
ALTER TABLE sites ADD COLUMN process_noise DOUBLE PRECISION;
