-- cliffwatch schema, version 7: each point's displacement series also kept packed, so that a long
-- series is read as a few hundred blobs instead of one row (17 columns) per epoch
-- (docs/performance.md, section "Service"). The displacements table stays the truth; these are
-- derived from it in the same write transaction (store::series_blocks).
--
-- Rows observed up to a site's sealed_until are packed, per point, into immutable blocks of at
-- most 128 epochs (store::series_record's layout); later rows (the tail) are read as rows. A site
-- without a series_seals row has no blocks: its whole series is tail.
--
-- Existing data: nothing to convert here. Until its site is sealed, a series is served from the
-- rows as before (correct, only slower); Store::open packs every site that has displacements and
-- no series_seals row (store::series_blocks::backfill), one write transaction per site. Packing
-- needs the floats' bytes, which SQL cannot produce portably, hence Rust and not this file.
-- Portable SQL as in version 1 (BLOB: PostgreSQL BYTEA).

CREATE TABLE series_blocks (
    site_id   TEXT NOT NULL,
    point     TEXT NOT NULL,
    -- observed_at of the block's last and first rows (store form)
    last_at   TEXT NOT NULL,
    first_at  TEXT NOT NULL,
    n_rows    BIGINT NOT NULL,
    -- format byte, then the rows oldest first (store::series_record)
    data      BLOB NOT NULL,
    PRIMARY KEY (site_id, point, last_at)
);

-- per site: rows observed up to sealed_until are in series_blocks (none: '');
-- pending counts the epochs stored since, to know when the next block is full
CREATE TABLE series_seals (
    site_id       TEXT PRIMARY KEY REFERENCES sites (id),
    sealed_until  TEXT NOT NULL,
    pending       BIGINT NOT NULL
);
