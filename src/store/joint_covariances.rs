//! The joint covariance an epoch's adjustment computed (of all its points, or of the datum and
//! block points in large networks): the point names as a JSON array in matrix order, and the
//! matrix's upper triangle, row by row, as little-endian f64 (`upper_m2`, m²): 8 bytes a value
//! and half the matrix, against ≈ 21 bytes of JSON text for every value of the whole matrix.
//! Rows stored before migration `20261126001400` (SQLite) / `20261126000400` (PostgreSQL) hold
//! the whole row-major matrix as JSON text in `matrix_m2` instead; both are read.

use sqlx::AnyExecutor;

use super::series::record::f64_at;
use super::StoreError;
use cliffwatch_core::analysis::JointCovarianceM2;

/// Stores the joint covariance of `points` (row-major 3n × 3n `matrix_m2`, m²) for an epoch.
/// The matrix is taken as symmetric: only its upper triangle is kept.
pub async fn insert(
    db: impl AnyExecutor<'_>,
    site: &str,
    epoch: i64,
    points: &[String],
    matrix_m2: &[f64],
) -> Result<(), StoreError> {
    let upper = pack_upper(matrix_m2, 3 * points.len())?;
    sqlx::query(
        "INSERT INTO joint_covariances (site_id, epoch_id, points, upper_m2) VALUES ($1, $2, $3, $4)",
    )
    .bind(site)
    .bind(epoch)
    .bind(serde_json::to_string(points)?)
    .bind(upper)
    .execute(db)
    .await?;
    Ok(())
}

/// The joint covariance stored for an epoch, as a row-major 3n × 3n matrix (m²); None when the
/// epoch has none.
pub async fn get(
    db: impl AnyExecutor<'_>,
    site: &str,
    epoch: i64,
) -> Result<Option<JointCovarianceM2>, StoreError> {
    let row: Option<(String, Option<Vec<u8>>, Option<String>)> = sqlx::query_as(
        "SELECT points, upper_m2, matrix_m2 FROM joint_covariances WHERE site_id = $1 AND epoch_id = $2",
    )
    .bind(site)
    .bind(epoch)
    .fetch_optional(db)
    .await?;
    let Some((points, upper, legacy)) = row else {
        return Ok(None);
    };
    let points: Vec<String> = serde_json::from_str(&points)?;
    let n = 3 * points.len();
    let matrix_m2 = match (upper, legacy) {
        (Some(bytes), _) => unpack_upper(&bytes, n)?,
        (None, Some(json)) => serde_json::from_str(&json)?,
        (None, None) => {
            return Err(StoreError::Corrupt(format!(
                "joint covariance of epoch {epoch} of site '{site}' has no matrix"
            )))
        }
    };
    if matrix_m2.len() != n * n {
        return Err(StoreError::Corrupt(format!(
            "joint covariance of epoch {epoch} of site '{site}': {} values for {} points",
            matrix_m2.len(),
            points.len()
        )));
    }
    Ok(Some(JointCovarianceM2 { points, matrix_m2 }))
}

/// The upper triangle (diagonal included) of the row-major `n` × `n` `matrix`, row by row, as
/// little-endian f64 bytes.
pub fn pack_upper(matrix: &[f64], n: usize) -> Result<Vec<u8>, StoreError> {
    if matrix.len() != n * n {
        return Err(StoreError::Corrupt(format!(
            "joint covariance: {} values for a {n} × {n} matrix",
            matrix.len()
        )));
    }
    let mut out = Vec::with_capacity(n * (n + 1) / 2 * 8);
    for i in 0..n {
        for v in &matrix[i * n + i..(i + 1) * n] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    Ok(out)
}

/// The row-major `n` × `n` symmetric matrix whose upper triangle [`pack_upper`] wrote.
pub fn unpack_upper(bytes: &[u8], n: usize) -> Result<Vec<f64>, StoreError> {
    if bytes.len() != n * (n + 1) / 2 * 8 {
        return Err(StoreError::Corrupt(format!(
            "joint covariance: {} bytes for the upper triangle of a {n} × {n} matrix",
            bytes.len()
        )));
    }
    let mut m = vec![0.0; n * n];
    let mut at = 0;
    for i in 0..n {
        for j in i..n {
            let v = f64_at(bytes, at);
            at += 8;
            m[i * n + j] = v;
            m[j * n + i] = v;
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_upper_triangle_gives_the_symmetric_matrix_back_bit_for_bit() {
        let n = 6;
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            for j in i..n {
                let v = 1e-6 / (1.0 + i as f64 + 0.37 * j as f64)
                    * if (i + j) % 3 == 0 { -1.0 } else { 1.0 };
                m[i * n + j] = v;
                m[j * n + i] = v;
            }
        }
        let bytes = pack_upper(&m, n).unwrap();
        assert_eq!(bytes.len(), 21 * 8);
        let back = unpack_upper(&bytes, n).unwrap();
        assert!(back.iter().zip(&m).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn a_wrong_size_is_refused() {
        assert!(pack_upper(&[1.0; 8], 3).is_err());
        assert!(unpack_upper(&[0u8; 40], 3).is_err());
        assert!(unpack_upper(&[0u8; 48], 3).is_ok());
    }
}
