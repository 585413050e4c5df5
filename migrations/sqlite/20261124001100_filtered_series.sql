-- Issue 12: the series serves the Kalman filter's values and the forecast's σ; declared blocks
-- get their own motion series.
ALTER TABLE displacements ADD COLUMN time_to_failure_sigma_hours DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_dx_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_dy_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_dz_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_d_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_dx_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_dy_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_dz_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_d_mm DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_velocity_mm_per_day DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_velocity_mm_per_day DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_acceleration_mm_per_day2 DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_acceleration_mm_per_day2 DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN f_time_to_failure_hours DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN sigma_f_time_to_failure_hours DOUBLE PRECISION;

-- The motion of each declared block per epoch, as a point's row: `block` names the group.
CREATE TABLE block_motions (
    site_id                TEXT NOT NULL,
    epoch_id               BIGINT NOT NULL,
    block                  TEXT NOT NULL,
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
) WITHOUT ROWID;

-- The version of the analysis that produced a site's stored series: a site below the binary's
-- version is recomputed at start (existing databases gain the filtered values this way).
ALTER TABLE sites ADD COLUMN analysis_version BIGINT NOT NULL DEFAULT 0;
