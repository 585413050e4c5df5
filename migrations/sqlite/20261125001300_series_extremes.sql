-- Issue 13: each packed series block also keeps its extremes (the first and last rows and those
-- where dx, dy, dz and d are smallest and largest; store::series_record::extremes), so that the
-- plot of a long history reads ~10 rows per block instead of 128 (docs/performance.md, section
-- "Dashboard"). The extremes come before the data, so that reading them does not walk the data's
-- overflow pages.
--
-- Existing data: the blocks are derived data. They are dropped here with their seals, and
-- Store::open packs every site again from its displacements (store::series_blocks::backfill), one
-- write transaction per site, now with the extremes.

DELETE FROM series_seals;
DROP TABLE series_blocks;
CREATE TABLE series_blocks (
    site_id   TEXT NOT NULL,
    point     TEXT NOT NULL,
    -- observed_at of the block's last and first rows (store form)
    last_at   TEXT NOT NULL,
    first_at  TEXT NOT NULL,
    n_rows    BIGINT NOT NULL,
    -- format byte, then the block's extreme rows oldest first (store::series_record)
    extremes  BLOB NOT NULL,
    -- format byte, then the rows oldest first (store::series_record)
    data      BLOB NOT NULL,
    PRIMARY KEY (site_id, point, last_at)
);
