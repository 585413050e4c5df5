-- Retention of the raw observations (service::retention): when an epoch's observations were
-- deleted (store format), NULL while they are kept. The partial index lists the epochs that
-- still hold theirs by time, so a pass reads only those older than its cut.
ALTER TABLE epochs ADD COLUMN observations_pruned_at TEXT;
CREATE INDEX epochs_keeping_observations ON epochs (observed_at) WHERE observations_pruned_at IS NULL;
