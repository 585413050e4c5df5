//! The face plan: the points drawn in the best-fit plane of the cliff face, along the face
//! against height, whatever the site frame (pure geometry, no I/O).
//!
//! The plane is the least-squares plane through the points (its normal is the eigenvector of the
//! smallest eigenvalue of their scatter matrix). Height is the frame's third axis (Up in E, N, Up
//! and in the local frames of the upload form) projected into the plane; when the face is nearly
//! horizontal the plane's longest in-plane direction is used instead. "Along the face" completes
//! the pair (up × normal), oriented with the frame's first axis where it can.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// The plane's frame: origin and unit axes in the site frame (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacePlane {
    /// Centroid of the points (site frame, m).
    pub origin: [f64; 3],
    /// Unit vector along the face.
    pub along: [f64; 3],
    /// Unit vector up the face.
    pub up: [f64; 3],
    /// Unit normal of the face.
    pub normal: [f64; 3],
}

impl FacePlane {
    /// Least-squares plane through `points` (site frame, m). `None` for fewer than three points
    /// or points that are (nearly) all on one line.
    pub fn fit(points: &[[f64; 3]]) -> Option<FacePlane> {
        if points.len() < 3 {
            return None;
        }
        let n = points.len() as f64;
        let c = points
            .iter()
            .fold(Vector3::zeros(), |s, p| s + Vector3::from(*p))
            / n;
        let mut m = Matrix3::zeros();
        for p in points {
            let d = Vector3::from(*p) - c;
            m += d * d.transpose();
        }
        let eig = SymmetricEigen::new(m);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let (small, mid, large) = (
            eig.eigenvalues[order[0]],
            eig.eigenvalues[order[1]],
            eig.eigenvalues[order[2]],
        );
        if !(large.is_finite() && large > 0.0) || mid <= 1e-9 * large || !small.is_finite() {
            return None;
        }
        let normal: Vector3<f64> = eig.eigenvectors.column(order[0]).into_owned();
        let z = Vector3::z();
        let up_in_plane = z - normal * normal.dot(&z);
        let up = if up_in_plane.norm() > 0.2 {
            up_in_plane.normalize()
        } else {
            eig.eigenvectors.column(order[2]).into_owned().normalize()
        };
        let mut along = up.cross(&normal).normalize();
        // Orient "along" with the frame's first axis (or second) where it can.
        let lead = if along.x.abs() > 0.1 {
            along.x
        } else {
            along.y
        };
        if lead < 0.0 {
            along = -along;
        }
        let normal = along.cross(&up);
        Some(FacePlane {
            origin: c.into(),
            along: along.into(),
            up: up.into(),
            normal: normal.into(),
        })
    }

    /// Plan coordinates (along, up) of a point in m.
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        let d = Vector3::from(p) - Vector3::from(self.origin);
        [
            d.dot(&Vector3::from(self.along)),
            d.dot(&Vector3::from(self.up)),
        ]
    }

    /// In-plane components (along, up) of a displacement vector, in its own unit.
    pub fn project_vector(&self, v: [f64; 3]) -> [f64; 2] {
        let v = Vector3::from(v);
        [
            v.dot(&Vector3::from(self.along)),
            v.dot(&Vector3::from(self.up)),
        ]
    }

    /// Out-of-plane component (along the normal) of a displacement vector, in its own unit.
    pub fn out_of_plane(&self, v: [f64; 3]) -> f64 {
        Vector3::from(v).dot(&Vector3::from(self.normal))
    }
}

/// A "nice" number (1, 2 or 5 × 10ⁿ) not above `x` (> 0).
pub fn nice_floor(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    let m = x / p;
    p * if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotated(p: [f64; 3], yaw: f64) -> [f64; 3] {
        let (s, c) = yaw.sin_cos();
        [
            c * p[0] - s * p[1] + 500.0,
            s * p[0] + c * p[1] - 200.0,
            p[2] + 40.0,
        ]
    }

    /// A face leaning back 20° in a frame rotated by any azimuth: plan distances equal the
    /// distances in the face, height follows Up, and displacements along the normal do not
    /// show in the plan.
    #[test]
    fn plan_keeps_the_face_geometry_in_any_frame() {
        for yaw in [0.0f64, 0.7, 2.0, -2.8] {
            let tilt = 20f64.to_radians();
            let face: Vec<[f64; 3]> = (0..12)
                .map(|i| {
                    let (u, h) = ((i % 4) as f64 * 3.0, (i / 4) as f64 * 5.0);
                    [u, h * tilt.sin(), h * tilt.cos()]
                })
                .map(|p| rotated(p, yaw))
                .collect();
            let plane = FacePlane::fit(&face).expect("plane");
            let a = plane.project(face[0]);
            let b = plane.project(face[11]);
            let d3 = (0..3)
                .map(|k| (face[0][k] - face[11][k]).powi(2))
                .sum::<f64>()
                .sqrt();
            let d2 = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            assert!((d3 - d2).abs() < 1e-9, "yaw {yaw}: {d3} vs {d2}");
            // Higher rows are higher in the plan.
            assert!(plane.project(face[8])[1] > plane.project(face[0])[1] + 9.0);
            let n = plane.normal;
            let v = plane.project_vector([n[0] * 5.0, n[1] * 5.0, n[2] * 5.0]);
            assert!(v[0].abs() < 1e-9 && v[1].abs() < 1e-9);
            assert!((plane.out_of_plane([n[0], n[1], n[2]]) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn collinear_points_have_no_plane() {
        let line: Vec<[f64; 3]> = (0..5).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        assert!(FacePlane::fit(&line).is_none());
        assert!(FacePlane::fit(&line[..2]).is_none());
    }

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_floor(7.3), 5.0);
        assert_eq!(nice_floor(0.034), 0.02);
        assert_eq!(nice_floor(1.0), 1.0);
        assert_eq!(nice_floor(0.0), 1.0);
    }
}
