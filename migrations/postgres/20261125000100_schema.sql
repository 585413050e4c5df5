-- cliffwatch schema for PostgreSQL: the same tables, columns and constraints as the SQLite
-- migrations in ../sqlite (applied there one version at a time), in one step. Keep the two in
-- step: a new SQLite migration gets its PostgreSQL twin here.
--
-- Differences, all of them:
-- - text keys and every text column use the "C" collation: the store relies on binary text
--   order (RFC 3339 timestamps, cursors, the open upper bound of range queries), SQLite's own;
-- - BYTEA for the packed series blocks (SQLite BLOB);
-- - no WITHOUT ROWID (SQLite's clustering clause); the primary keys are the same.

CREATE TABLE sites (
    id               TEXT COLLATE "C" PRIMARY KEY,
    name             TEXT COLLATE "C" NOT NULL,
    model            TEXT COLLATE "C" NOT NULL DEFAULT 'orthogonal',
    schedule_hours   DOUBLE PRECISION,
    confidence       DOUBLE PRECISION NOT NULL DEFAULT 0.99,
    alert_rules      TEXT COLLATE "C" NOT NULL DEFAULT '[]',
    reference_epoch  BIGINT,
    created_at       TEXT COLLATE "C" NOT NULL,
    reference_epochs BIGINT NOT NULL DEFAULT 1,
    process_noise    DOUBLE PRECISION,
    analysis_version BIGINT NOT NULL DEFAULT 0
);

CREATE TABLE cameras (
    site_id     TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    id          TEXT COLLATE "C" NOT NULL,
    definition  TEXT COLLATE "C" NOT NULL,
    updated_at  TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, id)
);

CREATE TABLE stations (
    site_id     TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    name        TEXT COLLATE "C" NOT NULL,
    first_epoch BIGINT NOT NULL,
    PRIMARY KEY (site_id, name)
);

CREATE TABLE points (
    site_id     TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    name        TEXT COLLATE "C" NOT NULL,
    role        TEXT COLLATE "C" NOT NULL DEFAULT 'monitored' CHECK (role IN ('stable', 'monitored')),
    grp         TEXT COLLATE "C",
    dir_x       DOUBLE PRECISION,
    dir_y       DOUBLE PRECISION,
    dir_z       DOUBLE PRECISION,
    PRIMARY KEY (site_id, name)
);

CREATE TABLE epochs (
    site_id      TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    id           BIGINT NOT NULL,
    observed_at  TEXT COLLATE "C" NOT NULL,
    label        TEXT COLLATE "C",
    status       TEXT COLLATE "C" NOT NULL,
    model        TEXT COLLATE "C" NOT NULL,
    sigma0_mm    DOUBLE PRECISION NOT NULL,
    c_mm         DOUBLE PRECISION,
    c_sigma_mm   DOUBLE PRECISION,
    iterations   BIGINT NOT NULL,
    body_sha256  TEXT COLLATE "C" NOT NULL,
    cameras      TEXT COLLATE "C" NOT NULL,
    report       TEXT COLLATE "C" NOT NULL,
    created_at   TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, id),
    UNIQUE (site_id, observed_at)
);

CREATE TABLE images (
    site_id      TEXT COLLATE "C" NOT NULL,
    epoch_id     BIGINT NOT NULL,
    id           TEXT COLLATE "C" NOT NULL,
    camera       TEXT COLLATE "C" NOT NULL,
    station      TEXT COLLATE "C" NOT NULL,
    seq          BIGINT NOT NULL,
    PRIMARY KEY (site_id, epoch_id, id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);

CREATE TABLE observations (
    site_id      TEXT COLLATE "C" NOT NULL,
    epoch_id     BIGINT NOT NULL,
    image_id     TEXT COLLATE "C" NOT NULL,
    point        TEXT COLLATE "C" NOT NULL,
    seq          BIGINT NOT NULL,
    x_mm         DOUBLE PRECISION,
    y_mm         DOUBLE PRECISION,
    col_px       DOUBLE PRECISION,
    row_px       DOUBLE PRECISION,
    vx_mm        DOUBLE PRECISION,
    vy_mm        DOUBLE PRECISION,
    w            DOUBLE PRECISION,
    dropped      BOOLEAN NOT NULL DEFAULT FALSE,
    PRIMARY KEY (site_id, epoch_id, image_id, point),
    FOREIGN KEY (site_id, epoch_id, image_id) REFERENCES images (site_id, epoch_id, id)
);

CREATE TABLE coordinates (
    site_id      TEXT COLLATE "C" NOT NULL,
    epoch_id     BIGINT NOT NULL,
    point        TEXT COLLATE "C" NOT NULL,
    observed_at  TEXT COLLATE "C" NOT NULL,
    x_m          DOUBLE PRECISION NOT NULL,
    y_m          DOUBLE PRECISION NOT NULL,
    z_m          DOUBLE PRECISION NOT NULL,
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

CREATE TABLE joint_covariances (
    site_id      TEXT COLLATE "C" NOT NULL,
    epoch_id     BIGINT NOT NULL,
    points       TEXT COLLATE "C" NOT NULL,
    matrix_m2    TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, epoch_id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);

CREATE TABLE displacements (
    site_id                TEXT COLLATE "C" NOT NULL,
    epoch_id               BIGINT NOT NULL,
    point                  TEXT COLLATE "C" NOT NULL,
    observed_at            TEXT COLLATE "C" NOT NULL,
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
    cov_dxdy_mm2           DOUBLE PRECISION,
    cov_dxdz_mm2           DOUBLE PRECISION,
    cov_dydz_mm2           DOUBLE PRECISION,
    time_to_failure_sigma_hours DOUBLE PRECISION,
    f_dx_mm DOUBLE PRECISION, f_dy_mm DOUBLE PRECISION, f_dz_mm DOUBLE PRECISION, f_d_mm DOUBLE PRECISION,
    sigma_f_dx_mm DOUBLE PRECISION, sigma_f_dy_mm DOUBLE PRECISION, sigma_f_dz_mm DOUBLE PRECISION,
    sigma_f_d_mm DOUBLE PRECISION,
    f_velocity_mm_per_day DOUBLE PRECISION, sigma_f_velocity_mm_per_day DOUBLE PRECISION,
    f_acceleration_mm_per_day2 DOUBLE PRECISION, sigma_f_acceleration_mm_per_day2 DOUBLE PRECISION,
    f_time_to_failure_hours DOUBLE PRECISION, sigma_f_time_to_failure_hours DOUBLE PRECISION,
    PRIMARY KEY (site_id, point, observed_at),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);
CREATE UNIQUE INDEX displacements_by_epoch ON displacements (site_id, epoch_id, point);

CREATE TABLE block_motions (
    site_id                TEXT COLLATE "C" NOT NULL,
    epoch_id               BIGINT NOT NULL,
    block                  TEXT COLLATE "C" NOT NULL,
    observed_at            TEXT COLLATE "C" NOT NULL,
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
    cov_dxdy_mm2           DOUBLE PRECISION,
    cov_dxdz_mm2           DOUBLE PRECISION,
    cov_dydz_mm2           DOUBLE PRECISION,
    time_to_failure_sigma_hours DOUBLE PRECISION,
    f_dx_mm DOUBLE PRECISION, f_dy_mm DOUBLE PRECISION, f_dz_mm DOUBLE PRECISION, f_d_mm DOUBLE PRECISION,
    sigma_f_dx_mm DOUBLE PRECISION, sigma_f_dy_mm DOUBLE PRECISION, sigma_f_dz_mm DOUBLE PRECISION,
    sigma_f_d_mm DOUBLE PRECISION,
    f_velocity_mm_per_day DOUBLE PRECISION, sigma_f_velocity_mm_per_day DOUBLE PRECISION,
    f_acceleration_mm_per_day2 DOUBLE PRECISION, sigma_f_acceleration_mm_per_day2 DOUBLE PRECISION,
    f_time_to_failure_hours DOUBLE PRECISION, sigma_f_time_to_failure_hours DOUBLE PRECISION,
    PRIMARY KEY (site_id, block, observed_at),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);

CREATE TABLE series_blocks (
    site_id   TEXT COLLATE "C" NOT NULL,
    point     TEXT COLLATE "C" NOT NULL,
    last_at   TEXT COLLATE "C" NOT NULL,
    first_at  TEXT COLLATE "C" NOT NULL,
    n_rows    BIGINT NOT NULL,
    data      BYTEA NOT NULL,
    PRIMARY KEY (site_id, point, last_at)
);

CREATE TABLE series_seals (
    site_id       TEXT COLLATE "C" PRIMARY KEY REFERENCES sites (id),
    sealed_until  TEXT COLLATE "C" NOT NULL,
    pending       BIGINT NOT NULL
);

CREATE TABLE groups (
    site_id        TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    name           TEXT COLLATE "C" NOT NULL,
    kind           TEXT COLLATE "C" NOT NULL CHECK (kind IN ('block')),
    direction      TEXT COLLATE "C",
    points         TEXT COLLATE "C" NOT NULL DEFAULT '[]',
    process_noise  DOUBLE PRECISION,
    updated_at     TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, name)
);

CREATE TABLE alerts (
    id               TEXT COLLATE "C" PRIMARY KEY,
    site_id          TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    point            TEXT COLLATE "C",
    points           TEXT COLLATE "C" NOT NULL DEFAULT '[]',
    level            TEXT COLLATE "C" NOT NULL CHECK (level IN ('watch', 'warning', 'alarm')),
    rule             TEXT COLLATE "C" NOT NULL,
    value            DOUBLE PRECISION,
    threshold        DOUBLE PRECISION,
    unit             TEXT COLLATE "C",
    epoch_id         BIGINT,
    observed_at      TEXT COLLATE "C",
    message          TEXT COLLATE "C" NOT NULL,
    state            TEXT COLLATE "C" NOT NULL CHECK (state IN ('open', 'acknowledged', 'resolved')),
    raised_at        TEXT COLLATE "C" NOT NULL,
    updated_at       TEXT COLLATE "C" NOT NULL,
    acknowledged_by  TEXT COLLATE "C",
    ack_comment      TEXT COLLATE "C",
    group_name       TEXT COLLATE "C"
);
CREATE INDEX alerts_by_time ON alerts (raised_at);
CREATE INDEX alerts_by_site ON alerts (site_id, state);

CREATE TABLE alert_states (
    site_id     TEXT COLLATE "C" PRIMARY KEY REFERENCES sites (id),
    state       TEXT COLLATE "C" NOT NULL,
    updated_at  TEXT COLLATE "C" NOT NULL
);

CREATE TABLE webhooks (
    id          TEXT COLLATE "C" PRIMARY KEY,
    url         TEXT COLLATE "C" NOT NULL,
    secret      TEXT COLLATE "C" NOT NULL,
    min_level   TEXT COLLATE "C" NOT NULL DEFAULT 'warning',
    source      TEXT COLLATE "C" NOT NULL DEFAULT 'api',
    created_at  TEXT COLLATE "C" NOT NULL,
    enabled     BOOLEAN NOT NULL DEFAULT TRUE,
    format      TEXT COLLATE "C" NOT NULL DEFAULT 'standard'
        CHECK (format IN ('standard', 'alertmanager_webhook', 'alertmanager_api_v2'))
);

CREATE TABLE webhook_outbox (
    id          TEXT COLLATE "C" PRIMARY KEY,
    event_type  TEXT COLLATE "C" NOT NULL,
    alert_id    TEXT COLLATE "C" REFERENCES alerts (id),
    level       TEXT COLLATE "C",
    payload     TEXT COLLATE "C" NOT NULL,
    created_at  TEXT COLLATE "C" NOT NULL
);

CREATE TABLE webhook_deliveries (
    outbox_id        TEXT COLLATE "C" NOT NULL REFERENCES webhook_outbox (id),
    webhook_id       TEXT COLLATE "C" NOT NULL,
    state            TEXT COLLATE "C" NOT NULL CHECK (state IN ('pending', 'delivered', 'failed')),
    attempts         BIGINT NOT NULL DEFAULT 0,
    next_attempt_at  TEXT COLLATE "C" NOT NULL,
    last_status      BIGINT,
    last_error       TEXT COLLATE "C",
    delivered_at     TEXT COLLATE "C",
    payload          TEXT COLLATE "C",
    PRIMARY KEY (outbox_id, webhook_id)
);
CREATE INDEX webhook_deliveries_due ON webhook_deliveries (state, next_attempt_at);

CREATE TABLE watch_orientations (
    site_id     TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    station     TEXT COLLATE "C" NOT NULL,
    camera      TEXT COLLATE "C" NOT NULL,
    rotation    TEXT COLLATE "C" NOT NULL,
    center      TEXT COLLATE "C" NOT NULL,
    epoch_id    BIGINT NOT NULL,
    updated_at  TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, station)
);

CREATE TABLE watch_folders (
    site_id   TEXT COLLATE "C" NOT NULL REFERENCES sites (id),
    hash      TEXT COLLATE "C" NOT NULL,
    epoch_id  BIGINT NOT NULL,
    taken_at  TEXT COLLATE "C" NOT NULL,
    PRIMARY KEY (site_id, hash)
);
