-- Issue 59: how the watched directory detects a site's targets (JSON: optional `polarity`,
-- `min_diameter_px`, `max_diameter_px`); NULL: the detector's defaults.
ALTER TABLE sites ADD COLUMN detection TEXT;
