-- Issue 77: a site retired (no more uploads, pages kept, alerts closed) and when its data was
-- last exported: it may be deleted only once retired and exported after the retirement.
ALTER TABLE sites ADD COLUMN retired_at TEXT;
ALTER TABLE sites ADD COLUMN retired_reason TEXT;
ALTER TABLE sites ADD COLUMN exported_at TEXT;
