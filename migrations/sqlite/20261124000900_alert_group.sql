-- Block-group alerts (issue 12): the group whose block motion raised the alert (NULL for point and
-- site-level alerts).
ALTER TABLE alerts ADD COLUMN group_name TEXT;
