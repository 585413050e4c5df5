//! The face plan: the points drawn in the face, along the face against height, in the site's
//! declared frame (pure geometry, no I/O).
//!
//! The face's axes come from [`cliffwatch_core::analysis::site_frame::FaceAxes`]: the site's up axis and the
//! face's outward normal (declared, or from the stable points' least-squares plane). The plan's
//! origin is the centroid of the points.

use nalgebra::Vector3;

use cliffwatch_core::analysis::site_frame::{FaceAxes, SiteFrame};

/// The plane's frame: origin and unit axes in the site frame (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacePlane {
    /// Centroid of the points (site frame, m).
    pub origin: [f64; 3],
    /// The face's axes (along, up, out) and where the normal came from.
    pub axes: FaceAxes,
}

impl FacePlane {
    /// The plan of `all` points (site frame, m) in `frame`, the normal derived from `stable`
    /// when it is not declared. `None` when no face can be fitted (fewer than three points, points
    /// on one line) or the face is nearly horizontal.
    pub fn fit(frame: &SiteFrame, stable: &[[f64; 3]], all: &[[f64; 3]]) -> Option<FacePlane> {
        if all.is_empty() {
            return None;
        }
        let axes = FaceAxes::of(frame, stable, all)?;
        let n = all.len() as f64;
        let c = all
            .iter()
            .fold(Vector3::zeros(), |s, p| s + Vector3::from(*p))
            / n;
        Some(FacePlane {
            origin: c.into(),
            axes,
        })
    }

    /// Plan coordinates (along, up) of a point in m.
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        let d = Vector3::from(p) - Vector3::from(self.origin);
        let c = self.axes.components(d.into());
        [c[0], c[1]]
    }

    /// In-plane components (along, up) of a displacement vector, in its own unit.
    pub fn project_vector(&self, v: [f64; 3]) -> [f64; 2] {
        let c = self.axes.components(v);
        [c[0], c[1]]
    }

    /// Out-of-plane component (out of the face, towards the cameras) of a displacement vector,
    /// in its own unit.
    pub fn out_of_plane(&self, v: [f64; 3]) -> f64 {
        self.axes.components(v)[2]
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
            let plane = FacePlane::fit(&SiteFrame::default(), &face, &face).expect("plane");
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
            let n = plane.axes.out;
            let v = plane.project_vector([n[0] * 5.0, n[1] * 5.0, n[2] * 5.0]);
            assert!(v[0].abs() < 1e-9 && v[1].abs() < 1e-9);
            assert!((plane.out_of_plane([n[0], n[1], n[2]]) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn collinear_points_have_no_plane() {
        let line: Vec<[f64; 3]> = (0..5).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        let frame = SiteFrame::default();
        assert!(FacePlane::fit(&frame, &line, &line).is_none());
        assert!(FacePlane::fit(&frame, &line[..2], &line[..2]).is_none());
    }

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_floor(7.3), 5.0);
        assert_eq!(nice_floor(0.034), 0.02);
        assert_eq!(nice_floor(1.0), 1.0);
        assert_eq!(nice_floor(0.0), 1.0);
    }
}
