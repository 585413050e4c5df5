-- Issue 61: each epoch's variance components per camera (JSON, as in the report) as a column,
-- so that the a-priori σ estimate of the site page reads them without the epochs' whole reports.
ALTER TABLE epochs ADD COLUMN variance_components TEXT;
UPDATE epochs SET variance_components = json_extract(report, '$.variance_components')
 WHERE report LIKE '%"variance_components"%';
