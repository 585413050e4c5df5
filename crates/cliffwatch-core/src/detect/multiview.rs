//! Matching detections across the stations of one epoch with affine cameras (pure).
//!
//! At 100 m and more a telephoto image is close to an affine (orthogonal) projection, `x = M X + t`
//! with `M` 2 × 3 (the model of Ono & Hattori, eq (1)–(3), without the perspective correction). Points
//! seen in every view fix all views' affine cameras up to one common 3-D affine frame: the measurement
//! matrix of n ≥ 4 such points, centred per view, has rank 3 and its factorization (Tomasi & Kanade)
//! gives the cameras. Four points seeded in every station are enough; no object coordinates are used.
//! With the cameras, a detection in one view and one in another are the same target only if they lie on
//! each other's (affine) epipolar line; a third view then confirms the pair by the intersected point's
//! projection. A detection that could belong to two such tracks is left out, never guessed.

use std::collections::{HashMap, HashSet};

use nalgebra::{DMatrix, Matrix2x3, Matrix3, Matrix4x3, Vector2, Vector3, Vector4};

/// One station's affine camera: image = `m · X + t` in mm, X in the common affine frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineCamera {
    /// The 2 × 3 linear part (mm per frame unit).
    pub m: Matrix2x3<f64>,
    /// The image of the frame's origin in mm.
    pub t: Vector2<f64>,
}

impl AffineCamera {
    /// Image of `x` (affine frame) in mm.
    pub fn project(&self, x: &Vector3<f64>) -> [f64; 2] {
        let p = self.m * x + self.t;
        [p[0], p[1]]
    }
}

/// Affine cameras of `views.len()` views from points seen in all of them (`views[i][k]`: image of
/// point k in view i, mm), by a rank-3 factorization of the centred measurement matrix. Returns the
/// cameras, the points in their frame and the rms misfit per coordinate in mm; None with fewer than 4
/// points, fewer than 2 views, or points that span fewer than 3 dimensions.
pub fn factorize(views: &[Vec<[f64; 2]>]) -> Option<(Vec<AffineCamera>, Vec<Vector3<f64>>, f64)> {
    let m = views.len();
    let n = views.first()?.len();
    if m < 2 || n < 4 || views.iter().any(|v| v.len() != n) {
        return None;
    }
    let mut w = DMatrix::<f64>::zeros(2 * m, n);
    let mut t = vec![Vector2::zeros(); m];
    for (i, v) in views.iter().enumerate() {
        for p in v {
            t[i] += Vector2::new(p[0], p[1]) / n as f64;
        }
        for (k, p) in v.iter().enumerate() {
            w[(2 * i, k)] = p[0] - t[i][0];
            w[(2 * i + 1, k)] = p[1] - t[i][1];
        }
    }
    let svd = w.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    // nalgebra does not promise sorted singular values: order them, largest first
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|a, b| svd.singular_values[*b].total_cmp(&svd.singular_values[*a]));
    if order.len() < 3 {
        return None;
    }
    let s: Vec<f64> = order.iter().map(|&k| svd.singular_values[k]).collect();
    if !(s[0] > 0.0 && s[2] > 1e-9 * s[0]) {
        return None;
    }
    let mut cams = Vec::with_capacity(m);
    for (i, ti) in t.iter().enumerate() {
        let mut mi = Matrix2x3::zeros();
        for r in 0..2 {
            for c in 0..3 {
                mi[(r, c)] = u[(2 * i + r, order[c])] * s[c].sqrt();
            }
        }
        cams.push(AffineCamera { m: mi, t: *ti });
    }
    let points: Vec<Vector3<f64>> = (0..n)
        .map(|k| Vector3::from_fn(|c, _| vt[(order[c], k)] * s[c].sqrt()))
        .collect();
    let resid: f64 = s.iter().skip(3).map(|x| x * x).sum();
    let rms = (resid / (2 * m * n) as f64).sqrt();
    Some((cams, points, rms))
}

/// Least-squares intersection of one point's images `(view, xy mm)`; returns the point and the largest
/// distance in mm between an image and the point's projection. None when the views do not fix it.
pub fn intersect(cams: &[AffineCamera], obs: &[(usize, [f64; 2])]) -> Option<(Vector3<f64>, f64)> {
    let mut n = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for &(v, p) in obs {
        let c = &cams[v];
        n += c.m.transpose() * c.m;
        b += c.m.transpose() * (Vector2::new(p[0], p[1]) - c.t);
    }
    let x = n.try_inverse()? * b;
    let worst = obs
        .iter()
        .map(|&(v, p)| {
            let q = cams[v].project(&x);
            (q[0] - p[0]).hypot(q[1] - p[1])
        })
        .fold(0.0, f64::max);
    Some((x, worst))
}

/// The unit vector n with nᵀ A = 0 for a 4 × 3 matrix of rank 3 (the affine fundamental constraint).
fn left_null(a: &Matrix4x3<f64>) -> Option<Vector4<f64>> {
    let n = (a * a.transpose()).symmetric_eigen();
    let k = n.eigenvalues.imin();
    let v = n.eigenvectors.column(k).into_owned();
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// A target found in several views: the detection per view (None where it was not found).
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Detection index per view.
    pub blobs: Vec<Option<usize>>,
    /// Intersected point in the affine frame.
    pub xyz: Vector3<f64>,
    /// Largest image misfit in mm.
    pub misfit_mm: f64,
}

impl Track {
    /// Number of views the track is found in.
    pub fn views(&self) -> usize {
        self.blobs.iter().flatten().count()
    }
}

/// Tracks and the detections left out because they fit two tracks.
#[derive(Debug, Clone, Default)]
pub struct Matching {
    /// Accepted tracks (the given ones first).
    pub tracks: Vec<Track>,
    /// Per view: detections that belonged to two competing tracks.
    pub ambiguous: Vec<Vec<usize>>,
}

/// The one unused detection within `tol` mm of `q` in one view; None when there is none or more
/// than one.
fn unique_near(blobs: &[[f64; 2]], used: &[bool], q: [f64; 2], tol: f64) -> Option<usize> {
    let tol2 = tol * tol;
    let mut found = None;
    for (j, b) in blobs.iter().enumerate() {
        let (dx, dy) = (b[0] - q[0], b[1] - q[1]);
        if dx * dx + dy * dy <= tol2 && !used[j] {
            if found.is_some() {
                return None;
            }
            found = Some(j);
        }
    }
    found
}

/// Builds tracks across views: `given` tracks (e.g. the seeds) are kept; every pair of unused detections
/// of two views on each other's epipolar line (misfit ≤ `tol_mm`) is intersected, projected into the
/// other views and completed by the one detection within `tol_mm` there. A candidate found in at least
/// `min_views` views is accepted unless a competing candidate (another detection in a view both use,
/// found in as many views, or one fewer) exists; then its detections are reported ambiguous.
pub fn match_tracks(
    cams: &[AffineCamera],
    blobs: &[&[[f64; 2]]],
    given: &[Vec<Option<usize>>],
    tol_mm: f64,
    min_views: usize,
) -> Matching {
    let m = cams.len();
    let mut used: Vec<Vec<bool>> = blobs.iter().map(|b| vec![false; b.len()]).collect();
    let mut out = Matching {
        tracks: Vec::new(),
        ambiguous: vec![Vec::new(); m],
    };
    take_given(cams, blobs, given, &mut used, &mut out);
    let mut cands = pair_candidates(cams, blobs, &used, tol_mm, min_views);
    take_unrivalled(&mut cands, &mut used, &mut out);
    for (v, amb) in out.ambiguous.iter_mut().enumerate() {
        amb.retain(|j| !used[v][*j]);
        amb.sort_unstable();
    }
    out
}

/// The given tracks (seeds, earlier identifications) that intersect: taken first, their
/// detections marked used.
fn take_given(
    cams: &[AffineCamera],
    blobs: &[&[[f64; 2]]],
    given: &[Vec<Option<usize>>],
    used: &mut [Vec<bool>],
    out: &mut Matching,
) {
    for g in given {
        let obs: Vec<(usize, [f64; 2])> = g
            .iter()
            .enumerate()
            .filter_map(|(v, b)| b.map(|j| (v, blobs[v][j])))
            .collect();
        if let Some((xyz, misfit_mm)) = intersect(cams, &obs) {
            for (v, b) in g.iter().enumerate() {
                if let Some(j) = b {
                    used[v][*j] = true;
                }
            }
            out.tracks.push(Track {
                blobs: g.clone(),
                xyz,
                misfit_mm,
            });
        }
    }
}

/// Every track found from a pair of views by the affine epipolar constraint and completed in the
/// other views, with a misfit within `tol_mm` (mm) and at least `min_views` views; each track once
/// however many of its pairs found it.
fn pair_candidates(
    cams: &[AffineCamera],
    blobs: &[&[[f64; 2]]],
    used: &[Vec<bool>],
    tol_mm: f64,
    min_views: usize,
) -> Vec<Track> {
    let m = cams.len();
    let mut cands: Vec<Track> = Vec::new();
    let mut seen: HashSet<Vec<Option<usize>>> = HashSet::new();
    for r in 0..m {
        for i in r + 1..m {
            // the affine epipolar constraint of views r and i: n · [x_r − t_r; x_i − t_i] = 0 with n the
            // left null vector of [M_r; M_i] (4 × 3); the distance to the line in view i is
            // |n · …| / |(n₂, n₃)|
            let mut a4 = Matrix4x3::zeros();
            a4.fixed_view_mut::<2, 3>(0, 0).copy_from(&cams[r].m);
            a4.fixed_view_mut::<2, 3>(2, 0).copy_from(&cams[i].m);
            let Some(n) = left_null(&a4) else { continue };
            let scale = n[2].hypot(n[3]).max(n[0].hypot(n[1]));
            if scale <= 0.0 {
                continue;
            }
            let along_r: Vec<f64> = blobs[r]
                .iter()
                .map(|p| (n[0] * (p[0] - cams[r].t[0]) + n[1] * (p[1] - cams[r].t[1])) / scale)
                .collect();
            let along_i: Vec<f64> = blobs[i]
                .iter()
                .map(|p| (n[2] * (p[0] - cams[i].t[0]) + n[3] * (p[1] - cams[i].t[1])) / scale)
                .collect();
            for (a, pa) in blobs[r].iter().enumerate() {
                if used[r][a] {
                    continue;
                }
                for (b, pb) in blobs[i].iter().enumerate() {
                    if used[i][b] || (along_r[a] + along_i[b]).abs() > 2.0 * tol_mm {
                        continue;
                    }
                    let Some((x2, f2)) = intersect(cams, &[(r, *pa), (i, *pb)]) else {
                        continue;
                    };
                    if f2 > tol_mm {
                        continue;
                    }
                    let mut track = vec![None; m];
                    track[r] = Some(a);
                    track[i] = Some(b);
                    for v in (0..m).filter(|&v| v != r && v != i) {
                        track[v] = unique_near(blobs[v], &used[v], cams[v].project(&x2), tol_mm);
                    }
                    if seen.contains(&track) {
                        continue;
                    }
                    let obs: Vec<(usize, [f64; 2])> = track
                        .iter()
                        .enumerate()
                        .filter_map(|(v, b)| b.map(|j| (v, blobs[v][j])))
                        .collect();
                    let Some((xyz, misfit_mm)) = intersect(cams, &obs) else {
                        continue;
                    };
                    if misfit_mm <= tol_mm && obs.len() >= min_views.max(2) {
                        // the same track found from another pair of its views is one candidate
                        seen.insert(track.clone());
                        cands.push(Track {
                            blobs: track,
                            xyz,
                            misfit_mm,
                        });
                    }
                }
            }
        }
    }
    cands
}

/// Takes the candidates, most views and smallest misfit first, that no rival with about as many
/// views contradicts; a candidate with rivals is left out with them, and their detections are
/// reported ambiguous.
fn take_unrivalled(cands: &mut [Track], used: &mut [Vec<bool>], out: &mut Matching) {
    cands.sort_by(|a, b| {
        b.views()
            .cmp(&a.views())
            .then(a.misfit_mm.total_cmp(&b.misfit_mm))
    });
    // candidates per (view, detection), to find rivals
    let mut by_blob: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (k, c) in cands.iter().enumerate() {
        for (v, b) in c.blobs.iter().enumerate() {
            if let Some(j) = b {
                by_blob.entry((v, *j)).or_default().push(k);
            }
        }
    }
    let conflicts = |a: &Track, b: &Track| {
        a.blobs
            .iter()
            .zip(&b.blobs)
            .any(|(x, y)| x.is_some() && y.is_some() && x != y)
    };
    let mut rejected = vec![false; cands.len()];
    for k in 0..cands.len() {
        let c = &cands[k];
        if rejected[k]
            || c.blobs
                .iter()
                .enumerate()
                .any(|(v, b)| b.is_some_and(|j| used[v][j]))
        {
            continue;
        }
        let mut rivals: Vec<usize> = c
            .blobs
            .iter()
            .enumerate()
            .filter_map(|(v, b)| b.and_then(|j| by_blob.get(&(v, j))))
            .flatten()
            .copied()
            .filter(|&l| l != k && cands[l].views() + 1 >= c.views() && conflicts(c, &cands[l]))
            .collect();
        rivals.sort_unstable();
        rivals.dedup();
        if !rivals.is_empty() {
            for l in std::iter::once(k).chain(rivals) {
                rejected[l] = true;
                for (v, b) in cands[l].blobs.iter().enumerate() {
                    if let Some(j) = b {
                        if !used[v][*j] && !out.ambiguous[v].contains(j) {
                            out.ambiguous[v].push(*j);
                        }
                    }
                }
            }
            continue;
        }
        for (v, b) in c.blobs.iter().enumerate() {
            if let Some(j) = b {
                used[v][*j] = true;
            }
        }
        out.tracks.push(c.clone());
    }
}

/// Median distance from each detection to its nearest neighbour in mm (∞ with fewer than 2).
pub fn median_spacing(blobs: &[[f64; 2]]) -> f64 {
    let points: Vec<Vector3<f64>> = blobs
        .iter()
        .map(|b| Vector3::new(b[0], b[1], 0.0))
        .collect();
    super::naming::median_spacing(&points)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cams() -> Vec<AffineCamera> {
        // three orthographic views turned about the vertical axis by −20°, 0°, 25°; scale 4 mm/m
        [-20.0f64, 0.0, 25.0]
            .iter()
            .map(|deg| {
                let (s, c) = deg.to_radians().sin_cos();
                AffineCamera {
                    m: Matrix2x3::new(4.0 * c, 0.0, 4.0 * s, 0.0, 4.0, 0.0),
                    t: Vector2::new(0.3, -0.2),
                }
            })
            .collect()
    }

    fn grid() -> Vec<Vector3<f64>> {
        (0..20)
            .map(|k| {
                let (c, r) = ((k % 5) as f64, (k / 5) as f64);
                Vector3::new(
                    0.8 * c + 0.05 * r,
                    0.7 * r + 0.1 * ((k * 3) % 4) as f64,
                    0.6 * ((k * 7) % 5) as f64 / 5.0,
                )
            })
            .collect()
    }

    #[test]
    fn factorization_reproduces_the_images_and_matching_finds_every_target() {
        let (cams, pts) = (cams(), grid());
        let images: Vec<Vec<[f64; 2]>> = cams
            .iter()
            .map(|c| pts.iter().map(|p| c.project(p)).collect())
            .collect();
        // four seeds → cameras in some affine frame
        let seeds: Vec<Vec<[f64; 2]>> = images
            .iter()
            .map(|v| vec![v[0], v[4], v[15], v[12]])
            .collect();
        let (fcams, _, rms) = factorize(&seeds).unwrap();
        assert!(rms < 1e-9, "{rms}");
        // shuffled detections per view
        let blobs: Vec<Vec<[f64; 2]>> = images
            .iter()
            .enumerate()
            .map(|(v, im)| {
                let mut b = im.clone();
                b.rotate_left(3 * v + 1);
                b
            })
            .collect();
        let refs: Vec<&[[f64; 2]]> = blobs.iter().map(|b| b.as_slice()).collect();
        let m = match_tracks(&fcams, &refs, &[], 0.05, 3);
        assert_eq!(m.tracks.len(), 20, "{m:?}");
        for t in &m.tracks {
            // the same target in every view: the original index agrees
            let orig: Vec<usize> = t
                .blobs
                .iter()
                .enumerate()
                .map(|(v, b)| (b.unwrap() + 3 * v + 1) % 20)
                .collect();
            assert!(orig.iter().all(|o| *o == orig[0]), "{orig:?}");
        }
    }

    #[test]
    fn a_detection_fitting_two_tracks_is_ambiguous() {
        let cams = cams();
        let pts = grid();
        let mut images: Vec<Vec<[f64; 2]>> = cams
            .iter()
            .map(|c| pts.iter().map(|p| c.project(p)).collect())
            .collect();
        // a clutter blob on view 2 right beside target 7's image
        let q = images[2][7];
        images[2].push([q[0] + 0.02, q[1]]);
        let seeds: Vec<Vec<[f64; 2]>> = images
            .iter()
            .map(|v| vec![v[0], v[4], v[15], v[12]])
            .collect();
        let (fcams, _, _) = factorize(&seeds).unwrap();
        let refs: Vec<&[[f64; 2]]> = images.iter().map(|b| b.as_slice()).collect();
        let m = match_tracks(&fcams, &refs, &[], 0.05, 3);
        assert!(
            m.ambiguous[2].contains(&7) && m.ambiguous[2].contains(&20),
            "{:?}",
            m.ambiguous
        );
        assert!(m
            .tracks
            .iter()
            .all(|t| t.blobs[2] != Some(7) && t.blobs[2] != Some(20)));
    }

    #[test]
    fn too_few_points_or_flat_points_do_not_factorize() {
        let v = vec![vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]; 3];
        assert!(factorize(&v).is_none());
        let line = vec![vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]; 3];
        assert!(factorize(&line).is_none());
    }
}
