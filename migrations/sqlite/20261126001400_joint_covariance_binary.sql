-- The joint covariance as binary: the upper triangle, row by row, little-endian f64 (m²) in
-- upper_m2. Rows stored before keep their whole matrix as JSON text in matrix_m2, now nullable
-- (store/joint_covariances.rs reads both). SQLite cannot drop a NOT NULL: the table is rebuilt.
CREATE TABLE joint_covariances_binary (
    site_id      TEXT NOT NULL,
    epoch_id     BIGINT NOT NULL,
    points       TEXT NOT NULL,  -- JSON array of point names, matrix order
    matrix_m2    TEXT,           -- rows before this migration: JSON array, row-major 3n x 3n, m^2
    upper_m2     BLOB,           -- upper triangle row by row, little-endian f64, m^2
    PRIMARY KEY (site_id, epoch_id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id),
    CHECK (upper_m2 IS NOT NULL OR matrix_m2 IS NOT NULL)
);
INSERT INTO joint_covariances_binary (site_id, epoch_id, points, matrix_m2)
    SELECT site_id, epoch_id, points, matrix_m2 FROM joint_covariances;
DROP TABLE joint_covariances;
ALTER TABLE joint_covariances_binary RENAME TO joint_covariances;
