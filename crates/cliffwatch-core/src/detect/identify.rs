//! Identification: which detected blob is which known target (pure).
//!
//! The known points (site frame, m) are projected through the station's orientation: the previous
//! epoch's, or for a station seen for the first time one found by resection from ≥ 4 seed
//! observations. Each projection is matched to the detections inside its gate, a circle of radius
//! `scale · max_motion_m + orientation uncertainty` (mm on the image), where `scale = c / depth` is the
//! image scale at the point. A match is kept only when it is mutual and unique: a blob inside the gates
//! of two points, or a point with two blobs in its gate, is left out and listed as ambiguous — never
//! guessed. When the first pass finds fewer than half the targets in view, the station was set up
//! again or re-aimed: the pattern's shift on the image is found by voting
//! (`super::re_pointing`) and the matching repeated. Then a 2-D similarity from the unique
//! matches to the detections absorbs the rest of the re-pointing, and the matching is repeated.

use super::re_pointing::{translation_by_votes, MIN_VOTES};
use crate::photogrammetry::model::camera::brown_correct;
use crate::photogrammetry::start::start_values::{resect_image, StartImage};
use crate::photogrammetry::{Camera, ImageOrientation};
use nalgebra::Vector3;
use std::collections::BTreeMap;

/// Why identification could not run.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// Fewer than 4 usable seed observations for a first orientation.
    #[error("{0} seed observations; at least 4 distinct known points are needed")]
    TooFewSeeds(usize),
    /// A seed names a point that is not among the known points.
    #[error("seed observation of unknown point {0:?}")]
    UnknownSeedPoint(String),
    /// The resection from the seeds failed.
    #[error("resection from the seeds failed: {0}")]
    Resection(String),
    /// An input value is not finite or out of range.
    #[error("invalid identification input: {0}")]
    Invalid(String),
}

/// One seed observation of a first epoch: a known point measured by hand on the image.
#[derive(Debug, Clone, PartialEq)]
pub struct Seed {
    /// Point name (a key of the known points).
    pub point: String,
    /// Measured image coordinates in mm (x right, y up, from the image centre).
    pub xy_mm: [f64; 2],
}

/// How the station's orientation is known.
#[derive(Debug, Clone, Copy)]
pub enum Prior<'a> {
    /// The station's orientation from a previous epoch.
    Orientation(&'a ImageOrientation),
    /// ≥ 4 seed observations (first epoch of the station).
    Seeds(&'a [Seed]),
}

/// Options of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    /// Largest expected object motion of a target since the orientation's epoch, in m.
    pub max_motion_m: f64,
    /// Uncertainty of a projected position from the orientation itself, in image mm (re-pointing of
    /// the station, seed errors); with seeds, at least 5 × the seeds' residual RMS is used.
    pub orientation_mm: f64,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        Self {
            max_motion_m: 0.05,
            orientation_mm: 0.02,
        }
    }
}

/// One identified target.
#[derive(Debug, Clone, PartialEq)]
pub struct Identified {
    /// Point name.
    pub point: String,
    /// Index of the detection in the input list.
    pub blob: usize,
    /// Measured image x in mm.
    pub x_mm: f64,
    /// Measured image y in mm.
    pub y_mm: f64,
    /// Distance from the (similarity-corrected) projection in mm.
    pub offset_mm: f64,
}

/// The outcome of [`identify`].
#[derive(Debug, Clone)]
pub struct Identification {
    /// Unique, mutual matches, in the order of the known points' names.
    pub matched: Vec<Identified>,
    /// Detections inside no gate (clutter, or targets not in the known list).
    pub unmatched_blobs: Vec<usize>,
    /// Detections inside the gates of two or more points, or sharing a point's gate with another
    /// detection: left out.
    pub ambiguous_blobs: Vec<usize>,
    /// Points with two or more detections in their gate, or sharing their only detection with
    /// another point: left out.
    pub ambiguous_points: Vec<String>,
    /// Points projected inside the image area with no detection in their gate.
    pub missing_points: Vec<String>,
    /// The orientation used (the previous one, or the resection of the seeds).
    pub orientation: ImageOrientation,
    /// Gate radius per point in mm.
    pub gates_mm: BTreeMap<String, f64>,
}

fn finite2(v: [f64; 2]) -> bool {
    v[0].is_finite() && v[1].is_finite()
}

/// Orientation of a station from ≥ 4 image measurements of known points (`seeds`, image mm) by
/// resection (coordinates shifted to the points' centroid), and the RMS of the residuals in mm.
pub fn resect_seeds(
    seeds: &[Seed],
    known: &BTreeMap<String, [f64; 3]>,
    camera: &Camera,
) -> Result<(ImageOrientation, f64), IdentifyError> {
    let mut pts: Vec<(String, [f64; 3], [f64; 2])> = Vec::new();
    for s in seeds {
        let x = known
            .get(&s.point)
            .ok_or_else(|| IdentifyError::UnknownSeedPoint(s.point.clone()))?;
        if !finite2(s.xy_mm) {
            return Err(IdentifyError::Invalid(format!(
                "seed {} not finite",
                s.point
            )));
        }
        if !pts.iter().any(|p| p.0 == s.point) {
            pts.push((s.point.clone(), *x, s.xy_mm));
        }
    }
    if pts.len() < 4 {
        return Err(IdentifyError::TooFewSeeds(pts.len()));
    }
    let n = pts.len() as f64;
    let mut o = [0.0; 3];
    for p in &pts {
        for k in 0..3 {
            o[k] += p.1[k] / n;
        }
    }
    let known_v: Vec<Option<Vector3<f64>>> = pts
        .iter()
        .map(|p| Some(Vector3::new(p.1[0] - o[0], p.1[1] - o[1], p.1[2] - o[2])))
        .collect();
    let im = StartImage {
        id: "seeds".into(),
        c: camera.params[0],
        observations: pts
            .iter()
            .enumerate()
            .map(|(k, p)| (k, brown_correct(p.2, &camera.params)))
            .collect(),
    };
    let res = resect_image(&im, &known_v).map_err(|e| IdentifyError::Resection(e.to_string()))?;
    let mut rotation = [[0.0; 3]; 3];
    for (i, row) in rotation.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = res.rotation[(i, j)];
        }
    }
    let orientation = ImageOrientation {
        image: String::new(),
        station: String::new(),
        camera: camera.id.clone(),
        rotation,
        center: [
            res.center[0] + o[0],
            res.center[1] + o[1],
            res.center[2] + o[2],
        ],
    };
    let mut ss = 0.0;
    for p in &pts {
        let q = orientation
            .project(camera, p.1)
            .ok_or_else(|| IdentifyError::Resection("a seed point is behind the camera".into()))?;
        ss += (q[0] - p.2[0]).powi(2) + (q[1] - p.2[1]).powi(2);
    }
    Ok((orientation, (ss / n).sqrt()))
}

/// 2-D similarity `[a, b, tx, ty]` (x' = a x − b y + tx, y' = b x + a y + ty) from pairs, least squares.
fn similarity(pairs: &[([f64; 2], [f64; 2])]) -> Option<[f64; 4]> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (mut mx, mut my, mut nx, mut ny) = (0.0, 0.0, 0.0, 0.0);
    for (p, q) in pairs {
        mx += p[0] / n;
        my += p[1] / n;
        nx += q[0] / n;
        ny += q[1] / n;
    }
    let (mut sa, mut sb, mut sp) = (0.0, 0.0, 0.0);
    for (p, q) in pairs {
        let (px, py, qx, qy) = (p[0] - mx, p[1] - my, q[0] - nx, q[1] - ny);
        sa += px * qx + py * qy;
        sb += px * qy - py * qx;
        sp += px * px + py * py;
    }
    if sp <= 0.0 {
        return None;
    }
    let (a, b) = (sa / sp, sb / sp);
    Some([a, b, nx - (a * mx - b * my), ny - (b * mx + a * my)])
}

struct Pass {
    matched: Vec<(usize, usize, f64)>,
    amb_points: Vec<usize>,
    amb_blobs: Vec<usize>,
    missing: Vec<usize>,
    unmatched: Vec<usize>,
}

/// Mutual unique matching of projections (with gates) to blobs.
fn match_pass(proj: &[([f64; 2], f64)], blobs: &[[f64; 2]], inside: &[bool]) -> Pass {
    let mut cand_p: Vec<Vec<(usize, f64)>> = vec![Vec::new(); proj.len()];
    let mut cand_b: Vec<Vec<usize>> = vec![Vec::new(); blobs.len()];
    for (i, (q, g)) in proj.iter().enumerate() {
        for (j, b) in blobs.iter().enumerate() {
            let d = (b[0] - q[0]).hypot(b[1] - q[1]);
            if d <= *g {
                cand_p[i].push((j, d));
                cand_b[j].push(i);
            }
        }
    }
    let mut out = Pass {
        matched: Vec::new(),
        amb_points: Vec::new(),
        amb_blobs: Vec::new(),
        missing: Vec::new(),
        unmatched: Vec::new(),
    };
    for (i, c) in cand_p.iter().enumerate() {
        match c.as_slice() {
            [] => {
                if inside[i] {
                    out.missing.push(i);
                }
            }
            [(j, d)] if cand_b[*j].len() == 1 => out.matched.push((i, *j, *d)),
            _ => out.amb_points.push(i),
        }
    }
    for (j, c) in cand_b.iter().enumerate() {
        match c.len() {
            0 => out.unmatched.push(j),
            1 if cand_p[c[0]].len() == 1 => {}
            _ => out.amb_blobs.push(j),
        }
    }
    out
}

/// Identifies detections (image mm, x right, y up, from the image centre, e.g. from
/// [`super::Target::image_mm`]) as the `known` points (name → [X, Y, Z] m, site frame) seen by a station
/// with `camera`, from a previous orientation or seeds. Never guesses: see [`Identification`].
pub fn identify(
    blobs_mm: &[[f64; 2]],
    known: &BTreeMap<String, [f64; 3]>,
    camera: &Camera,
    prior: Prior<'_>,
    opts: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    if !(opts.max_motion_m.is_finite()
        && opts.max_motion_m >= 0.0
        && opts.orientation_mm.is_finite()
        && opts.orientation_mm >= 0.0)
    {
        return Err(IdentifyError::Invalid(format!("{opts:?}")));
    }
    if let Some(b) = blobs_mm.iter().find(|b| !finite2(**b)) {
        return Err(IdentifyError::Invalid(format!(
            "detection {b:?} not finite"
        )));
    }
    let c = camera.params[0];
    if !(c.is_finite() && c > 0.0) {
        return Err(IdentifyError::Invalid(format!("principal distance {c}")));
    }
    let (orientation, orient_mm) = match prior {
        Prior::Orientation(o) => (o.clone(), opts.orientation_mm),
        Prior::Seeds(seeds) => {
            let (o, rms) = resect_seeds(seeds, known, camera)?;
            (o, opts.orientation_mm.max(5.0 * rms))
        }
    };
    let half = camera.half_sensor_mm();
    let in_view = |q: [f64; 2]| half.is_none_or(|h| q[0].abs() <= h[0] && q[1].abs() <= h[1]);
    // projections with their gates; points behind the camera are left out
    let mut names = Vec::new();
    let mut proj = Vec::new();
    let mut inside = Vec::new();
    for (name, x) in known {
        if !(x[0].is_finite() && x[1].is_finite() && x[2].is_finite()) {
            return Err(IdentifyError::Invalid(format!("point {name} not finite")));
        }
        let Some(q) = orientation.project(camera, *x) else {
            continue;
        };
        if !finite2(q) {
            continue;
        }
        let r = &orientation.rotation;
        let d: Vec<f64> = (0..3).map(|k| x[k] - orientation.center[k]).collect();
        let depth = -(r[2][0] * d[0] + r[2][1] * d[1] + r[2][2] * d[2]);
        let gate = c / depth * opts.max_motion_m + orient_mm;
        names.push(name.clone());
        inside.push(in_view(q));
        proj.push((q, gate));
    }
    let mut pass = match_pass(&proj, blobs_mm, &inside);
    // a station set up again: the pattern moved by more than the gates; find the shift by votes
    let expected = inside.iter().filter(|i| **i).count();
    if pass.matched.len() < MIN_VOTES.max(expected / 2) {
        if let Some(t) = translation_by_votes(&proj, blobs_mm) {
            for (k, (q, _)) in proj.iter_mut().enumerate() {
                *q = [q[0] + t[0], q[1] + t[1]];
                inside[k] = in_view(*q);
            }
            pass = match_pass(&proj, blobs_mm, &inside);
        }
    }
    // absorb a small re-pointing: similarity from the unique matches, then match again
    let pairs: Vec<([f64; 2], [f64; 2])> = pass
        .matched
        .iter()
        .map(|&(i, j, _)| (proj[i].0, blobs_mm[j]))
        .collect();
    if let Some(s) = similarity(&pairs) {
        let moved: Vec<([f64; 2], f64)> = proj
            .iter()
            .map(|(q, g)| {
                (
                    [
                        s[0] * q[0] - s[1] * q[1] + s[2],
                        s[1] * q[0] + s[0] * q[1] + s[3],
                    ],
                    *g,
                )
            })
            .collect();
        if moved.iter().all(|m| finite2(m.0)) {
            pass = match_pass(&moved, blobs_mm, &inside);
        }
    }
    let gates_mm = names
        .iter()
        .zip(&proj)
        .map(|(n, p)| (n.clone(), p.1))
        .collect();
    Ok(Identification {
        matched: pass
            .matched
            .iter()
            .map(|&(i, j, d)| Identified {
                point: names[i].clone(),
                blob: j,
                x_mm: blobs_mm[j][0],
                y_mm: blobs_mm[j][1],
                offset_mm: d,
            })
            .collect(),
        unmatched_blobs: pass.unmatched,
        ambiguous_blobs: pass.amb_blobs,
        ambiguous_points: pass.amb_points.iter().map(|&i| names[i].clone()).collect(),
        missing_points: pass.missing.iter().map(|&i| names[i].clone()).collect(),
        orientation,
        gates_mm,
    })
}
