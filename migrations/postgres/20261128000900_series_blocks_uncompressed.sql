-- Issue 14: the packed series blocks are stored without compression. A block (~128 rows, ~25 kB)
-- is always read whole, and decompressing it (pglz) was ~15 % of reading a 10-year series
-- (docs/performance.md, section "Service"); packed doubles compress poorly on real data.
-- Blocks written before this migration keep their compression until they are rewritten; both
-- read the same.
ALTER TABLE series_blocks ALTER COLUMN data SET STORAGE EXTERNAL;
