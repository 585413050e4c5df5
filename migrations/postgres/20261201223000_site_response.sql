-- Issue 61: what the on-call staff of a site are to do and whom to call, shown in every page's
-- headline (a site setting; contacts as a JSON array of strings).
ALTER TABLE sites ADD COLUMN response_text TEXT COLLATE "C";
ALTER TABLE sites ADD COLUMN contacts TEXT COLLATE "C";
