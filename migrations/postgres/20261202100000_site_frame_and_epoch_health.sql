-- Issue 61: the site frame's orientation (JSON: `up`, optional `face_normal`); NULL: Z up and
-- the face's normal derived from the stable points' plane.
ALTER TABLE sites ADD COLUMN frame TEXT;
-- Issue 61: each epoch's variance factor and redundancy as columns, so that the site page and
-- the report show the adjustments' health without reading every report.
ALTER TABLE epochs ADD COLUMN variance_factor DOUBLE PRECISION;
ALTER TABLE epochs ADD COLUMN dof BIGINT;
UPDATE epochs SET variance_factor = (report::json ->> 'variance_factor')::double precision,
                  dof = (report::json ->> 'dof')::bigint;
-- Issue 61: which a-priori σ a site's adjustments use: `upload` (NULL, the cameras' as uploaded)
-- or `estimated` (each camera's from the variance components of the site's recent epochs).
ALTER TABLE sites ADD COLUMN apriori_sigma TEXT;
