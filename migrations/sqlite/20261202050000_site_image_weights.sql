-- Issue 59: how the watched directory weights a site's image observations: `camera` (NULL, the
-- camera's one a-priori σ) or `target` (each detected target's own σ).
ALTER TABLE sites ADD COLUMN image_weights TEXT;
