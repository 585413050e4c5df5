-- Each epoch's number of observations dropped by data snooping, so that a list of epochs (the
-- site page's, the API's) need not read every epoch's report to count them.
ALTER TABLE epochs ADD COLUMN dropped_observations BIGINT NOT NULL DEFAULT 0;
UPDATE epochs SET dropped_observations = (
    SELECT COUNT(*) FROM observations o
    WHERE o.site_id = epochs.site_id AND o.epoch_id = epochs.id AND o.dropped
);
