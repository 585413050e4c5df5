//! What an adjustment returns besides the contract's report: coordinates with full precision,
//! exterior orientations (for target identification) and the joint covariance of chosen points
//! (for the displacement analysis).

use super::report::AdjustmentReport;
use crate::photogrammetry::model::camera::{brown_distort, Camera};

/// One adjusted point: coordinates in m (site frame) and covariance in m² (σ0²·Qxx).
#[derive(Debug, Clone, PartialEq)]
pub struct AdjustedPoint {
    /// Point name.
    pub name: String,
    /// X, Y, Z in m.
    pub xyz: [f64; 3],
    /// 3 × 3 covariance in m², scaled by the a-posteriori variance factor.
    pub covariance_m2: [[f64; 3]; 3],
}

/// Exterior orientation of one image in the site frame: camera coordinates are `R (X − Xo)`, the
/// camera looks along −r3 (`docs/model.md`).
#[derive(Debug, Clone, PartialEq)]
pub struct ImageOrientation {
    /// Image id.
    pub image: String,
    /// Station name.
    pub station: String,
    /// Camera id.
    pub camera: String,
    /// Rotation R (rows r1, r2, r3), site frame.
    pub rotation: [[f64; 3]; 3],
    /// Projection centre Xo in m, site frame.
    pub center: [f64; 3],
}

impl ImageOrientation {
    /// Projects an object point (m, site frame) to measured image coordinates (mm, with the camera's
    /// distortion applied): collinearity, eq (2). None when the point is behind the camera.
    pub fn project(&self, camera: &Camera, xyz: [f64; 3]) -> Option<[f64; 2]> {
        let d = [
            xyz[0] - self.center[0],
            xyz[1] - self.center[1],
            xyz[2] - self.center[2],
        ];
        let r = &self.rotation;
        let dot = |row: &[f64; 3]| row[0] * d[0] + row[1] * d[1] + row[2] * d[2];
        let w = dot(&r[2]);
        if w >= 0.0 {
            return None;
        }
        let c = camera.params[0];
        let xc = [-c * dot(&r[0]) / w, -c * dot(&r[1]) / w];
        Some(brown_distort(xc, &camera.params))
    }
}

/// Joint covariance of a set of points: row-major 3n × 3n, m², ordered X, Y, Z per point.
#[derive(Debug, Clone, PartialEq)]
pub struct JointCovariance {
    /// Point names in matrix order.
    pub points: Vec<String>,
    /// Row-major 3n × 3n matrix in m².
    pub matrix_m2: Vec<f64>,
}

impl JointCovariance {
    /// Number of rows (3 × points).
    pub fn dim(&self) -> usize {
        3 * self.points.len()
    }

    /// Element (i, j) in m².
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.matrix_m2[i * self.dim() + j]
    }
}

/// The full result of an adjustment.
#[derive(Debug, Clone)]
pub struct Adjustment {
    /// The contract's report.
    pub report: AdjustmentReport,
    /// Adjusted points with covariances, in the order of the report.
    pub points: Vec<AdjustedPoint>,
    /// Exterior orientations, one per image.
    pub orientations: Vec<ImageOrientation>,
    /// Cameras with their adjusted interior parameters.
    pub cameras: Vec<Camera>,
    /// The joint covariance of [`AdjustOptions::joint_covariance_of`](crate::photogrammetry::AdjustOptions::joint_covariance_of) (points that exist in the epoch).
    pub joint_covariance: Option<JointCovariance>,
    /// Redundancy numbers and interior correlations, when
    /// [`AdjustOptions::design_statistics`](crate::photogrammetry::AdjustOptions::design_statistics)
    /// asked for them.
    pub design: Option<crate::photogrammetry::statistics::design::DesignStatistics>,
}

impl Adjustment {
    /// The adjusted point of that name.
    pub fn point(&self, name: &str) -> Option<&AdjustedPoint> {
        self.points.iter().find(|p| p.name == name)
    }
}
