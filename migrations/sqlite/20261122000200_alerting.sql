-- cliffwatch schema, version 2: the alert engine's state per site, and endpoints disabled after
-- a 410 Gone. Portable SQL as in version 1.

-- the analysis' AlertState of one site (JSON): open alerts and the rules' memory
CREATE TABLE alert_states (
    site_id     TEXT PRIMARY KEY REFERENCES sites (id),
    state       TEXT NOT NULL,
    updated_at  TEXT NOT NULL
);

-- FALSE after the endpoint answered 410 Gone: no more deliveries
ALTER TABLE webhooks ADD COLUMN enabled BOOLEAN NOT NULL DEFAULT TRUE;
