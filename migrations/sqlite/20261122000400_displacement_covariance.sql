-- cliffwatch schema, version 4: the off-diagonal terms of each displacement's 3 × 3 covariance
-- (mm²), so that clients can test a displacement against its full covariance (dᵀΣ⁻¹d), not only
-- per component. Null for rows stored before this version. Portable SQL as in version 1.
ALTER TABLE displacements ADD COLUMN cov_dxdy_mm2 DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN cov_dxdz_mm2 DOUBLE PRECISION;
ALTER TABLE displacements ADD COLUMN cov_dydz_mm2 DOUBLE PRECISION;
