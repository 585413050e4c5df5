//! The site frame's orientation: which axis is up and which way the face looks, so that a
//! displacement reads as "along the face, up the face, out of the face" whatever the frame (E, N,
//! Up; a local frame with Y up and Z towards the cameras; any rotation of them).
//!
//! A site declares its up axis (default +Z, as in E, N, Up) and, optionally, the face's outward
//! normal. Without a declared normal, the face is the least-squares plane through the stable
//! points (all points when fewer than three stable points span a plane), and its normal is
//! oriented so that "along the face" runs with the frame's first horizontal axis (+X where the
//! face is not across X, else +Y): declare the normal for a face that looks the other way.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

/// A site's declared orientation (the `frame` setting of a site).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct SiteFrame {
    /// The vertical (up) direction in the site frame, any length (e.g. `[0, 0, 1]` for E, N, Up,
    /// `[0, 1, 0]` for a local frame with Y up).
    #[serde(default = "default_up")]
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub up: [f64; 3],
    /// The face's outward normal (towards the cameras), any length; absent: derived from the
    /// stable points' plane (see the module's notes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub face_normal: Option<[f64; 3]>,
}

fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl Default for SiteFrame {
    fn default() -> Self {
        SiteFrame {
            up: default_up(),
            face_normal: None,
        }
    }
}

/// Largest |cos| between the up axis and a declared face normal: a face is at least 10° away
/// from horizontal, or "up the face" has no meaning.
const MAX_UP_NORMAL_COS: f64 = 0.985;

impl SiteFrame {
    /// Checks the declaration; the message names the field at fault.
    pub fn validate(&self) -> Result<(), String> {
        let up = unit(self.up).ok_or_else(|| {
            format!(
                "frame.up {:?}: a finite direction with a length above zero",
                self.up
            )
        })?;
        if let Some(n) = self.face_normal {
            let n = unit(n).ok_or_else(|| {
                format!("frame.face_normal {n:?}: a finite direction with a length above zero")
            })?;
            if n.dot(&up).abs() > MAX_UP_NORMAL_COS {
                return Err(format!(
                    "frame.face_normal {:?}: within 10° of frame.up; a face is steeper than that",
                    self.face_normal.unwrap_or_default()
                ));
            }
        }
        Ok(())
    }

    /// Axis names for a page: "+Y", "−Z", or the unit vector when it is not along an axis.
    pub fn describe(v: [f64; 3]) -> String {
        let Some(u) = unit(v) else {
            return "?".into();
        };
        for (k, name) in ["X", "Y", "Z"].iter().enumerate() {
            if (u[k].abs() - 1.0).abs() < 1e-9 {
                return format!("{}{name}", if u[k] > 0.0 { "+" } else { "−" });
            }
        }
        format!("({:.3}, {:.3}, {:.3})", u[0], u[1], u[2])
    }
}

/// Where the face's outward normal came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NormalSource {
    /// Declared in the site's `frame.face_normal`.
    Declared,
    /// The least-squares plane through the stable points.
    StablePoints,
    /// The least-squares plane through all points (fewer than three stable points span a plane).
    AllPoints,
}

/// The face's axes in the site frame: unit vectors, right-handed (`along × up = out`), so that a
/// viewer in front of the face sees "along" to the right and "up" upwards.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceAxes {
    /// Along the face, horizontal.
    pub along: [f64; 3],
    /// Up the face: the frame's up axis projected into the face.
    pub up: [f64; 3],
    /// Out of the face, towards the cameras.
    pub out: [f64; 3],
    /// Where `out` came from.
    pub source: NormalSource,
}

impl FaceAxes {
    /// The face's axes for `frame`, from the declared normal or the plane through `stable` (or
    /// `all` when the stable points do not span a plane), all in the site frame (m). `None` when
    /// no plane can be fitted or the face is within 10° of horizontal.
    pub fn of(frame: &SiteFrame, stable: &[[f64; 3]], all: &[[f64; 3]]) -> Option<FaceAxes> {
        let up = unit(frame.up)?;
        let (normal, source) = match frame.face_normal {
            Some(n) => (unit(n)?, NormalSource::Declared),
            None => match plane_normal(stable) {
                Some(n) => (n, NormalSource::StablePoints),
                None => (plane_normal(all)?, NormalSource::AllPoints),
            },
        };
        if normal.dot(&up).abs() > MAX_UP_NORMAL_COS {
            return None;
        }
        let up_in_face = (up - normal * normal.dot(&up)).normalize();
        let mut along = up_in_face.cross(&normal).normalize();
        if frame.face_normal.is_none() {
            // A derived normal has no side: take the one with "along" running with the frame's
            // first horizontal axis.
            let lead = if along.x.abs() > 0.1 {
                along.x
            } else if along.y.abs() > 0.1 {
                along.y
            } else {
                along.z
            };
            if lead < 0.0 {
                along = -along;
            }
        }
        let out = along.cross(&up_in_face);
        Some(FaceAxes {
            along: along.into(),
            up: up_in_face.into(),
            out: out.into(),
            source,
        })
    }

    /// Components (along, up, out) of a vector in the site frame, in its own unit.
    pub fn components(&self, v: [f64; 3]) -> [f64; 3] {
        let v = Vector3::from(v);
        [
            v.dot(&Vector3::from(self.along)),
            v.dot(&Vector3::from(self.up)),
            v.dot(&Vector3::from(self.out)),
        ]
    }

    /// Variances (mm² when `c` is in mm²) of the three components of a vector whose covariance in
    /// the site frame is `c`.
    pub fn component_variances(&self, c: &[[f64; 3]; 3]) -> [f64; 3] {
        let c = Matrix3::from_fn(|i, j| c[i][j]);
        [self.along, self.up, self.out].map(|a| {
            let a = Vector3::from(a);
            (a.transpose() * c * a)[(0, 0)]
        })
    }
}

fn unit(v: [f64; 3]) -> Option<Vector3<f64>> {
    let v = Vector3::from(v);
    let n = v.norm();
    (n.is_finite() && n > 1e-12).then(|| v / n)
}

/// The unit normal of the least-squares plane through `points` (the eigenvector of the smallest
/// eigenvalue of their scatter matrix); `None` for fewer than three points or points (nearly) on
/// one line.
fn plane_normal(points: &[[f64; 3]]) -> Option<Vector3<f64>> {
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
    Some(eig.eigenvectors.column(order[0]).into_owned().normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A face in a Y-up frame (Z towards the cameras) and the same face in E, N, Up (looking
    /// south, −N): the same components for the same motion, derived or declared.
    #[test]
    fn y_up_and_z_up_read_the_same_motion_alike() {
        let face: Vec<[f64; 3]> = (0..12)
            .map(|i| {
                let (u, h) = ((i % 4) as f64 * 3.0, (i / 4) as f64 * 5.0);
                [u, h, -0.3 * h + 0.01 * (i as f64).sin()]
            })
            .collect();
        let to_enu = |p: [f64; 3]| [p[0], -p[2], p[1]];
        let enu: Vec<[f64; 3]> = face.iter().map(|p| to_enu(*p)).collect();
        let y_up = SiteFrame {
            up: [0.0, 1.0, 0.0],
            face_normal: None,
        };
        let a = FaceAxes::of(&y_up, &face, &face).unwrap();
        let b = FaceAxes::of(&SiteFrame::default(), &enu, &enu).unwrap();
        let declared = SiteFrame {
            up: [0.0, 0.0, 2.0],
            face_normal: Some([0.0, -1.0, 0.3]),
        };
        let c = FaceAxes::of(&declared, &enu, &enu).unwrap();
        assert_eq!(a.source, NormalSource::StablePoints);
        assert_eq!(c.source, NormalSource::Declared);
        let slide = [0.5, -2.0, 1.5]; // right, down, out towards the cameras (Y-up frame)
        let ca = a.components(slide);
        let cb = b.components(to_enu(slide));
        let cc = c.components(to_enu(slide));
        for k in 0..3 {
            assert!((ca[k] - cb[k]).abs() < 1e-9, "{ca:?} vs {cb:?}");
            assert!((ca[k] - cc[k]).abs() < 1e-2, "{ca:?} vs {cc:?}");
        }
        // Down the face and out of it: negative up, positive out.
        assert!(ca[1] < -2.0 && ca[2] > 0.5 && ca[0] > 0.4, "{ca:?}");
    }

    #[test]
    fn declarations_are_checked() {
        let bad_up = SiteFrame {
            up: [0.0, 0.0, 0.0],
            face_normal: None,
        };
        assert!(bad_up.validate().unwrap_err().contains("frame.up"));
        let flat = SiteFrame {
            up: [0.0, 0.0, 1.0],
            face_normal: Some([0.0, 0.05, 1.0]),
        };
        assert!(flat.validate().unwrap_err().contains("frame.face_normal"));
        assert!(SiteFrame::default().validate().is_ok());
        assert_eq!(SiteFrame::describe([0.0, 2.0, 0.0]), "+Y");
        assert_eq!(SiteFrame::describe([0.0, 0.0, -1.0]), "−Z");
    }
}
