-- cliffwatch schema, version 1. Portable SQL: TEXT keys, RFC 3339 timestamps in TEXT
-- (fixed width, UTC, microseconds: they sort as text), JSON in TEXT, no SQLite-only clauses.
-- Lengths in the names: *_m metres, *_mm millimetres, *_m2 square metres.

CREATE TABLE sites (
    id              TEXT PRIMARY KEY,
    name            TEXT NOT NULL,
    model           TEXT NOT NULL DEFAULT 'orthogonal',
    schedule_hours  DOUBLE PRECISION,
    confidence      DOUBLE PRECISION NOT NULL DEFAULT 0.99,
    alert_rules     TEXT NOT NULL DEFAULT '[]',
    -- explicit reference epoch (PUT .../reference); NULL: the earliest observed_at
    reference_epoch BIGINT,
    created_at      TEXT NOT NULL
);

CREATE TABLE cameras (
    site_id     TEXT NOT NULL REFERENCES sites (id),
    id          TEXT NOT NULL,
    -- the latest upload-form definition of the camera (JSON): cameras of CSV uploads
    definition  TEXT NOT NULL,
    updated_at  TEXT NOT NULL,
    PRIMARY KEY (site_id, id)
);

CREATE TABLE stations (
    site_id     TEXT NOT NULL REFERENCES sites (id),
    name        TEXT NOT NULL,
    first_epoch BIGINT NOT NULL,
    PRIMARY KEY (site_id, name)
);

CREATE TABLE points (
    site_id     TEXT NOT NULL REFERENCES sites (id),
    name        TEXT NOT NULL,
    role        TEXT NOT NULL DEFAULT 'monitored' CHECK (role IN ('stable', 'monitored')),
    grp         TEXT,
    -- direction of interest (e.g. the cliff normal), site frame, not necessarily unit length
    dir_x       DOUBLE PRECISION,
    dir_y       DOUBLE PRECISION,
    dir_z       DOUBLE PRECISION,
    PRIMARY KEY (site_id, name)
);

CREATE TABLE epochs (
    site_id      TEXT NOT NULL REFERENCES sites (id),
    id           BIGINT NOT NULL,
    observed_at  TEXT NOT NULL,
    label        TEXT,
    status       TEXT NOT NULL,
    model        TEXT NOT NULL,
    sigma0_mm    DOUBLE PRECISION NOT NULL,
    c_mm         DOUBLE PRECISION,
    c_sigma_mm   DOUBLE PRECISION,
    iterations   BIGINT NOT NULL,
    -- sha256 (hex) of the canonical JSON of the parsed upload: idempotency
    body_sha256  TEXT NOT NULL,
    -- the cameras of the upload form (JSON array)
    cameras      TEXT NOT NULL,
    -- the adjustment report (JSON) without the residuals, which live in observations
    report       TEXT NOT NULL,
    created_at   TEXT NOT NULL,
    PRIMARY KEY (site_id, id),
    UNIQUE (site_id, observed_at)
);

CREATE TABLE images (
    site_id      TEXT NOT NULL,
    epoch_id     BIGINT NOT NULL,
    id           TEXT NOT NULL,
    camera       TEXT NOT NULL,
    station      TEXT NOT NULL,
    seq          BIGINT NOT NULL,
    PRIMARY KEY (site_id, epoch_id, id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);

CREATE TABLE observations (
    site_id      TEXT NOT NULL,
    epoch_id     BIGINT NOT NULL,
    image_id     TEXT NOT NULL,
    point        TEXT NOT NULL,
    seq          BIGINT NOT NULL,
    -- as given: mm or pixels
    x_mm         DOUBLE PRECISION,
    y_mm         DOUBLE PRECISION,
    col_px       DOUBLE PRECISION,
    row_px       DOUBLE PRECISION,
    -- residuals (observed - computed, mm), normalized residual, dropped by data snooping
    vx_mm        DOUBLE PRECISION,
    vy_mm        DOUBLE PRECISION,
    w            DOUBLE PRECISION,
    dropped      BOOLEAN NOT NULL DEFAULT FALSE,
    PRIMARY KEY (site_id, epoch_id, image_id, point),
    FOREIGN KEY (site_id, epoch_id, image_id) REFERENCES images (site_id, epoch_id, id)
);

CREATE TABLE coordinates (
    site_id      TEXT NOT NULL,
    epoch_id     BIGINT NOT NULL,
    point        TEXT NOT NULL,
    observed_at  TEXT NOT NULL,
    x_m          DOUBLE PRECISION NOT NULL,
    y_m          DOUBLE PRECISION NOT NULL,
    z_m          DOUBLE PRECISION NOT NULL,
    -- 3x3 covariance (m^2), upper triangle
    cxx_m2       DOUBLE PRECISION NOT NULL,
    cxy_m2       DOUBLE PRECISION NOT NULL,
    cxz_m2       DOUBLE PRECISION NOT NULL,
    cyy_m2       DOUBLE PRECISION NOT NULL,
    cyz_m2       DOUBLE PRECISION NOT NULL,
    czz_m2       DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (site_id, epoch_id, point),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id),
    FOREIGN KEY (site_id, point) REFERENCES points (site_id, name)
);
CREATE INDEX coordinates_by_point ON coordinates (site_id, point, observed_at);

-- joint covariance of the stable points of one epoch (what the congruence test needs)
CREATE TABLE joint_covariances (
    site_id      TEXT NOT NULL,
    epoch_id     BIGINT NOT NULL,
    points       TEXT NOT NULL,  -- JSON array of point names, matrix order
    matrix_m2    TEXT NOT NULL,  -- JSON array, row-major 3n x 3n, m^2
    PRIMARY KEY (site_id, epoch_id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);

CREATE TABLE displacements (
    site_id                TEXT NOT NULL,
    epoch_id               BIGINT NOT NULL,
    point                  TEXT NOT NULL,
    observed_at            TEXT NOT NULL,
    reference_epoch        BIGINT NOT NULL,
    dx_mm                  DOUBLE PRECISION NOT NULL,
    dy_mm                  DOUBLE PRECISION NOT NULL,
    dz_mm                  DOUBLE PRECISION NOT NULL,
    d_mm                   DOUBLE PRECISION NOT NULL,
    sigma_dx_mm            DOUBLE PRECISION NOT NULL,
    sigma_dy_mm            DOUBLE PRECISION NOT NULL,
    sigma_dz_mm            DOUBLE PRECISION NOT NULL,
    sigma_mm               DOUBLE PRECISION NOT NULL,
    d_along_mm             DOUBLE PRECISION,
    significant            BOOLEAN NOT NULL,
    velocity_mm_per_day    DOUBLE PRECISION,
    time_to_failure_hours  DOUBLE PRECISION,
    -- clustered by point and time: a time series is one contiguous range, not one page per row
    -- (observed_at is unique within a site). WITHOUT ROWID is SQLite's clustering clause; a
    -- PostgreSQL migration would use a plain primary key (and CLUSTER) instead.
    PRIMARY KEY (site_id, point, observed_at),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
) WITHOUT ROWID;
CREATE UNIQUE INDEX displacements_by_epoch ON displacements (site_id, epoch_id, point);

CREATE TABLE alerts (
    id               TEXT PRIMARY KEY,
    site_id          TEXT NOT NULL REFERENCES sites (id),
    point            TEXT,
    points           TEXT NOT NULL DEFAULT '[]',
    level            TEXT NOT NULL CHECK (level IN ('watch', 'warning', 'alarm')),
    rule             TEXT NOT NULL,
    value            DOUBLE PRECISION,
    threshold        DOUBLE PRECISION,
    unit             TEXT,
    epoch_id         BIGINT,
    observed_at      TEXT,
    message          TEXT NOT NULL,
    state            TEXT NOT NULL CHECK (state IN ('open', 'acknowledged', 'resolved')),
    raised_at        TEXT NOT NULL,
    updated_at       TEXT NOT NULL,
    acknowledged_by  TEXT,
    ack_comment      TEXT
);
CREATE INDEX alerts_by_time ON alerts (raised_at);
CREATE INDEX alerts_by_site ON alerts (site_id, state);

CREATE TABLE webhooks (
    id          TEXT PRIMARY KEY,
    url         TEXT NOT NULL,
    secret      TEXT NOT NULL,
    min_level   TEXT NOT NULL DEFAULT 'warning',
    -- 'api' or 'config' (from [[webhooks]] of the configuration file)
    source      TEXT NOT NULL DEFAULT 'api',
    created_at  TEXT NOT NULL
);

-- one row per event; its id is the webhook-id reused on every retry
CREATE TABLE webhook_outbox (
    id          TEXT PRIMARY KEY,
    event_type  TEXT NOT NULL,
    alert_id    TEXT REFERENCES alerts (id),
    level       TEXT,
    payload     TEXT NOT NULL,
    created_at  TEXT NOT NULL
);

-- delivery state of one event to one endpoint
CREATE TABLE webhook_deliveries (
    outbox_id        TEXT NOT NULL REFERENCES webhook_outbox (id),
    webhook_id       TEXT NOT NULL,
    state            TEXT NOT NULL CHECK (state IN ('pending', 'delivered', 'failed')),
    attempts         BIGINT NOT NULL DEFAULT 0,
    next_attempt_at  TEXT NOT NULL,
    last_status      BIGINT,
    last_error       TEXT,
    delivered_at     TEXT,
    PRIMARY KEY (outbox_id, webhook_id)
);
CREATE INDEX webhook_deliveries_due ON webhook_deliveries (state, next_attempt_at);
