-- State of the watched directory, kept in the database (backed up and restored with it) instead of
-- files under <watch_dir>/<site>/.state/.

-- The orientation of each station from its latest watched epoch (identification of the next one).
CREATE TABLE watch_orientations (
    site_id     TEXT NOT NULL REFERENCES sites (id),
    station     TEXT NOT NULL,
    camera      TEXT NOT NULL,
    -- rotation rows r1, r2, r3 (JSON [[a11, a12, a13], ...]); camera coordinates are R (X - Xo)
    rotation    TEXT NOT NULL,
    -- projection centre Xo in m (JSON [X, Y, Z], site frame)
    center      TEXT NOT NULL,
    epoch_id    BIGINT NOT NULL,
    updated_at  TEXT NOT NULL,
    PRIMARY KEY (site_id, station)
);

-- Content hashes of the folders taken, so a folder is never ingested twice.
CREATE TABLE watch_folders (
    site_id   TEXT NOT NULL REFERENCES sites (id),
    hash      TEXT NOT NULL,
    epoch_id  BIGINT NOT NULL,
    taken_at  TEXT NOT NULL,
    PRIMARY KEY (site_id, hash)
);
