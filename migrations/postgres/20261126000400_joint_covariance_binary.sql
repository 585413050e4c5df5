-- The joint covariance as binary: the upper triangle, row by row, little-endian f64 (m²) in
-- upper_m2. Rows stored before keep their whole matrix as JSON text in matrix_m2, now nullable
-- (store/joint_covariances.rs reads both). Doubles compress poorly: stored out of line without
-- TOAST's compression attempt.
ALTER TABLE joint_covariances ALTER COLUMN matrix_m2 DROP NOT NULL;
ALTER TABLE joint_covariances ADD COLUMN upper_m2 BYTEA;
ALTER TABLE joint_covariances ALTER COLUMN upper_m2 SET STORAGE EXTERNAL;
ALTER TABLE joint_covariances ADD CONSTRAINT joint_covariances_has_matrix
    CHECK (upper_m2 IS NOT NULL OR matrix_m2 IS NOT NULL);
