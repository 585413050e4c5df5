//! Naming intersected targets after the approximate coordinates (pure).
//!
//! The tracks of [`super::multiview`] are points in an affine frame; the approximations are points in
//! the site frame, each off by its own error. A 3-D affine map from the frame to the site is fitted to
//! the seeded tracks, then to every named track, alternating with a global one-to-one assignment
//! (Hungarian, `pathfinding::kuhn_munkres`) of tracks to approximations until the names stop changing.
//! The errors of the approximations average out in the map; each name is then judged on its own:
//! it is accepted only when every alternative (a free approximation, or a swap with another named
//! track) costs at least `margin` more in units of the approximations' scatter σ² — that is, when
//! the assignment wins by a likelihood ratio of at least e^(margin/2). Otherwise the track is ambiguous
//! and left unnamed.

use nalgebra::{DMatrix, Matrix3, Matrix3x4, Vector3};
use pathfinding::kuhn_munkres::kuhn_munkres;
use pathfinding::matrix::Matrix;

/// Options of [`name_tracks`].
#[derive(Debug, Clone, PartialEq)]
pub struct NamingOptions {
    /// Least cost of any alternative name, in units of σ² of the approximations (default 12: the
    /// chosen name is at least e⁶ ≈ 400 times as likely as the best other).
    pub margin: f64,
    /// Least σ assumed for the approximations in m (their scatter is estimated from the data).
    pub min_sigma_m: f64,
    /// Largest σ of the approximations, as a share of the targets' median spacing
    /// ([`Naming::spacing_m`]), at which names are given at all (default 0.3). Beyond it a
    /// neighbour's approximation lies within about 3 σ of most targets, the assignment picks the
    /// nearer approximations and so estimates σ too small, and the margin no longer protects
    /// against a wrong name (over 1000 simulated scenes with independent errors of 0.25 m, names
    /// went wrong in 2 scenes, both between 0.35 and 0.4): no target is named.
    pub max_sigma_per_spacing: f64,
}

impl Default for NamingOptions {
    fn default() -> Self {
        Self {
            margin: 12.0,
            min_sigma_m: 0.005,
            max_sigma_per_spacing: 0.3,
        }
    }
}

/// One track that could not be named with confidence.
#[derive(Debug, Clone, PartialEq)]
pub struct Ambiguity {
    /// Track index.
    pub track: usize,
    /// The name the assignment gave (index into the approximations).
    pub best: usize,
    /// The closest rival name.
    pub rival: usize,
    /// The rival's extra cost in units of σ².
    pub margin: f64,
}

/// The outcome of [`name_tracks`].
#[derive(Debug, Clone, PartialEq)]
pub struct Naming {
    /// Per track: the index of its approximation, when named.
    pub names: Vec<Option<usize>>,
    /// Tracks left unnamed because another name was almost as likely.
    pub ambiguous: Vec<Ambiguity>,
    /// Tracks far from every free approximation (more than 4 σ): not in the list, or clutter.
    pub unlisted: Vec<usize>,
    /// Scatter σ per coordinate of the approximations about the fitted map, m.
    pub sigma_m: f64,
    /// Median distance between neighbouring tracks brought into the site frame by the map, m: the
    /// targets' spacing as the images show it.
    pub spacing_m: f64,
    /// The scatter beyond which no target is named: `max_sigma_per_spacing` × `spacing_m`, m.
    pub max_sigma_m: f64,
    /// The map from the affine frame to the site frame (m).
    pub map: Matrix3x4<f64>,
}

/// Least-squares affine map `site = A x + b` from pairs; None when the points span fewer than 3 dimensions.
fn fit_affine(pairs: &[(Vector3<f64>, Vector3<f64>)]) -> Option<Matrix3x4<f64>> {
    if pairs.len() < 4 {
        return None;
    }
    let n = pairs.len();
    let mut a = DMatrix::<f64>::zeros(n, 4);
    let mut b = DMatrix::<f64>::zeros(n, 3);
    for (k, (x, y)) in pairs.iter().enumerate() {
        for c in 0..3 {
            a[(k, c)] = x[c];
            b[(k, c)] = y[c];
        }
        a[(k, 3)] = 1.0;
    }
    let sol = least_squares(a, &b, 1e-9)?; // 4 × 3
    Some(Matrix3x4::from_fn(|r, c| sol[(c, r)]))
}

/// Least-squares solution X of `a X = b`; None when a singular value of `a` is below `min_ratio` ×
/// the largest (the points do not span the map's dimensions).
fn least_squares(a: DMatrix<f64>, b: &DMatrix<f64>, min_ratio: f64) -> Option<DMatrix<f64>> {
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smin.is_nan() || smin <= min_ratio * smax {
        return None;
    }
    svd.solve(b, 1e-12 * smax).ok()
}

fn apply(map: &Matrix3x4<f64>, x: &Vector3<f64>) -> Vector3<f64> {
    map.fixed_view::<3, 3>(0, 0) * x + map.column(3)
}

/// Cost scale of the integer assignment: squared metres × 1e8 (0.1 mm²).
const SCALE: f64 = 1e8;
const FORBIDDEN: i64 = -1_000_000_000_000_000;

/// One-to-one assignment of tracks (rows) to approximations or to "no name" at `gate2` (m²); fixed
/// tracks keep their name. Returns the approximation per track.
fn assign(
    cost: &[Vec<f64>],
    fixed: &[Option<usize>],
    n_approx: usize,
    gate2: f64,
) -> Vec<Option<usize>> {
    let nt = cost.len();
    if nt == 0 {
        return Vec::new();
    }
    let taken: Vec<bool> = (0..n_approx).map(|j| fixed.contains(&Some(j))).collect();
    let mut w = Matrix::new(nt, n_approx + nt, FORBIDDEN);
    for k in 0..nt {
        match fixed[k] {
            Some(j) => w[(k, j)] = 0,
            None => {
                for j in (0..n_approx).filter(|&j| !taken[j]) {
                    w[(k, j)] = -((cost[k][j] * SCALE).round() as i64);
                }
            }
        }
        w[(k, n_approx + k)] = -((gate2 * SCALE).round() as i64);
    }
    let (_, cols) = kuhn_munkres(&w);
    cols.into_iter()
        .map(|j| (j < n_approx).then_some(j))
        .collect()
}

/// Median distance between neighbouring points (∞ with fewer than 2), in their unit.
pub fn median_spacing(points: &[Vector3<f64>]) -> f64 {
    let mut d: Vec<f64> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            points
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, q)| (p - q).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    if d.len() < 2 {
        return f64::INFINITY;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Centroid and the two main directions of a point set (its best-fit plane).
fn plane_of(points: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let n = points.len().max(1) as f64;
    let c = points.iter().fold(Vector3::zeros(), |a, p| a + p) / n;
    let cov = points
        .iter()
        .fold(Matrix3::zeros(), |a, p| a + (p - c) * (p - c).transpose());
    let e = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| e.eigenvalues[*b].total_cmp(&e.eigenvalues[*a]));
    (
        c,
        e.eigenvectors.column(order[0]).into_owned(),
        e.eigenvectors.column(order[1]).into_owned(),
    )
}

/// The first map: a 2-D affine map between the tracks' and the approximations' best-fit planes from
/// the seeds, a one-to-one assignment in that plane, then the 3-D affine map of all assigned pairs.
fn first_map_in_plane(
    tracks: &[Vector3<f64>],
    fixed: &[Option<usize>],
    approx: &[Vector3<f64>],
    spacing: f64,
) -> Option<Matrix3x4<f64>> {
    let (ct, t1, t2) = plane_of(tracks);
    let (ca, a1, a2) = plane_of(approx);
    let uv = |p: &Vector3<f64>, c: &Vector3<f64>, e1: &Vector3<f64>, e2: &Vector3<f64>| {
        Vector3::new((p - c).dot(e1), (p - c).dot(e2), 0.0)
    };
    let t2d: Vec<Vector3<f64>> = tracks.iter().map(|p| uv(p, &ct, &t1, &t2)).collect();
    let a2d: Vec<Vector3<f64>> = approx.iter().map(|p| uv(p, &ca, &a1, &a2)).collect();
    // 2-D affine map from the seeds: rows [u v 1] → [u' v']
    let seeds: Vec<(usize, usize)> = fixed
        .iter()
        .enumerate()
        .filter_map(|(k, f)| f.map(|j| (k, j)))
        .collect();
    if seeds.len() < 3 {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(seeds.len(), 3);
    let mut b = DMatrix::<f64>::zeros(seeds.len(), 2);
    for (r, &(k, j)) in seeds.iter().enumerate() {
        a[(r, 0)] = t2d[k][0];
        a[(r, 1)] = t2d[k][1];
        a[(r, 2)] = 1.0;
        b[(r, 0)] = a2d[j][0];
        b[(r, 1)] = a2d[j][1];
    }
    let m = least_squares(a, &b, 1e-6)?; // 3 × 2
    let cost: Vec<Vec<f64>> = t2d
        .iter()
        .map(|p| {
            let q = Vector3::new(
                m[(0, 0)] * p[0] + m[(1, 0)] * p[1] + m[(2, 0)],
                m[(0, 1)] * p[0] + m[(1, 1)] * p[1] + m[(2, 1)],
                0.0,
            );
            a2d.iter().map(|w| (q - w).norm_squared()).collect()
        })
        .collect();
    let names = assign(&cost, fixed, approx.len(), spacing * spacing);
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = names
        .iter()
        .enumerate()
        .filter_map(|(k, n)| n.map(|j| (tracks[k], approx[j])))
        .collect();
    fit_affine(&pairs)
}

/// Tracks and approximations taken into the local re-assignment of one track.
const NEIGHBOURHOOD: usize = 30;

/// The cheapest other name of track `k` (named `j`): the optimal assignment of the `NEIGHBOURHOOD`
/// tracks nearest to it, among their names and the free approximations nearby, with `k`–`j`
/// forbidden, against the same assignment unconstrained. Any chain of re-namings within the
/// neighbourhood counts, not only swaps of two. Returns (extra cost in m², rival approximation).
#[allow(clippy::too_many_arguments)]
fn rival(
    k: usize,
    j: usize,
    pred: &[Vector3<f64>],
    names: &[Option<usize>],
    fixed: &[Option<usize>],
    used: &[bool],
    cost: &[Vec<f64>],
    gate2: f64,
) -> (f64, usize) {
    let by_distance = |n: usize, d: &dyn Fn(usize) -> f64| {
        let mut idx: Vec<usize> = (0..n).collect();
        idx.sort_by(|a, b| d(*a).total_cmp(&d(*b)));
        idx
    };
    let rows: Vec<usize> = by_distance(pred.len(), &|l| (pred[l] - pred[k]).norm_squared())
        .into_iter()
        .filter(|&l| fixed[l].is_none())
        .take(NEIGHBOURHOOD)
        .collect();
    let mut cols: Vec<usize> = rows.iter().filter_map(|&l| names[l]).collect();
    cols.extend(
        by_distance(used.len(), &|c| cost[k][c])
            .into_iter()
            .filter(|&c| !used[c])
            .take(NEIGHBOURHOOD),
    );
    let solve = |forbid: bool| -> (i64, Vec<usize>) {
        let mut w = Matrix::new(rows.len(), cols.len() + rows.len(), FORBIDDEN);
        for (r, &l) in rows.iter().enumerate() {
            for (c, &a) in cols.iter().enumerate() {
                if !(forbid && l == k && a == j) {
                    w[(r, c)] = -((cost[l][a] * SCALE).round() as i64);
                }
            }
            w[(r, cols.len() + r)] = -((gate2 * SCALE).round() as i64);
        }
        kuhn_munkres(&w)
    };
    let (free_total, _) = solve(false);
    let (forced_total, assignment) = solve(true);
    let r = rows.iter().position(|&l| l == k).unwrap_or(0);
    let other = cols.get(assignment[r]).copied().unwrap_or(j);
    ((free_total - forced_total) as f64 / SCALE, other)
}

/// Each track's position predicted in the site frame by `map` (m), and its squared distance
/// (m²) to every approximation.
fn predictions_and_costs(
    tracks: &[Vector3<f64>],
    map: &Matrix3x4<f64>,
    approx: &[Vector3<f64>],
) -> (Vec<Vector3<f64>>, Vec<Vec<f64>>) {
    let pred: Vec<Vector3<f64>> = tracks.iter().map(|x| apply(map, x)).collect();
    let cost = pred
        .iter()
        .map(|p| approx.iter().map(|a| (p - a).norm_squared()).collect())
        .collect();
    (pred, cost)
}

/// Alternates assignment and map until the names settle (at most 10 rounds): each round assigns
/// within 5 σ, refits the map to the seeds and the pairs within 4 σ, and takes σ (m per
/// coordinate) from the refit's scatter. Returns the map and σ.
fn refine_map(
    tracks: &[Vector3<f64>],
    fixed: &[Option<usize>],
    approx: &[Vector3<f64>],
    mut map: Matrix3x4<f64>,
    mut sigma: f64,
    opts: &NamingOptions,
) -> (Matrix3x4<f64>, f64) {
    let mut names: Vec<Option<usize>> = fixed.to_vec();
    for _ in 0..10 {
        let (_, cost) = predictions_and_costs(tracks, &map, approx);
        let next = assign(&cost, fixed, approx.len(), (5.0 * sigma).powi(2));
        // refit on the assigned pairs within 4 σ (the seeds always)
        let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = next
            .iter()
            .enumerate()
            .filter_map(|(k, n)| {
                n.filter(|&j| fixed[k].is_some() || cost[k][j] <= (4.0 * sigma).powi(2))
                    .map(|j| (tracks[k], approx[j]))
            })
            .collect();
        let changed = next != names;
        names = next;
        if let Some(m) = fit_affine(&pairs) {
            map = m;
            let dof = (3 * pairs.len()).saturating_sub(12).max(1) as f64;
            let ss: f64 = pairs
                .iter()
                .map(|(x, y)| (apply(&map, x) - y).norm_squared())
                .sum();
            sigma = (ss / dof).sqrt().max(opts.min_sigma_m);
        }
        if !changed {
            break;
        }
    }
    (map, sigma)
}

/// The names kept: a name whose best re-naming (see `rival`) is less than `opts.margin` times σ²
/// worse is left out as ambiguous, and when most names are in doubt the map itself is not
/// trusted and none is kept; nor when σ exceeds `max_sigma` ([`Naming::max_sigma_m`]).
/// Returns the kept names, the ambiguities and the unlisted tracks.
fn leave_out_doubtful(
    names: &[Option<usize>],
    fixed: &[Option<usize>],
    pred: &[Vector3<f64>],
    cost: &[Vec<f64>],
    (sigma, max_sigma): (f64, f64),
    opts: &NamingOptions,
) -> (Vec<Option<usize>>, Vec<Ambiguity>, Vec<usize>) {
    let s2 = sigma * sigma;
    let n_approx = cost.first().map_or(0, Vec::len);
    let used: Vec<bool> = (0..n_approx).map(|j| names.contains(&Some(j))).collect();
    let mut ambiguous = Vec::new();
    let mut unlisted = Vec::new();
    let mut out = names.to_vec();
    for k in 0..names.len() {
        if fixed[k].is_some() {
            continue;
        }
        let Some(j) = names[k] else {
            unlisted.push(k);
            continue;
        };
        let best = rival(k, j, pred, names, fixed, &used, cost, (5.0 * sigma).powi(2));
        let margin = best.0 / s2;
        if margin < opts.margin {
            out[k] = None;
            ambiguous.push(Ambiguity {
                track: k,
                best: j,
                rival: best.1,
                margin,
            });
        }
    }
    // When most names are in doubt the map itself is not to be trusted, and approximations as
    // rough as 0.3 of the spacing name nothing reliably: name none.
    let candidates = (0..names.len())
        .filter(|&k| fixed[k].is_none() && names[k].is_some())
        .count();
    if 2 * ambiguous.len() > candidates || sigma > max_sigma {
        for k in 0..names.len() {
            if fixed[k].is_none() && out[k].is_some() {
                out[k] = None;
                ambiguous.push(Ambiguity {
                    track: k,
                    best: names[k].unwrap_or(0),
                    rival: names[k].unwrap_or(0),
                    margin: 0.0,
                });
            }
        }
    }
    (out, ambiguous, unlisted)
}

/// Names `tracks` (affine frame) after `approx` (site frame, m); `fixed[k]` is the approximation a
/// seeded track is known to be. Needs ≥ 4 fixed tracks spanning 3 dimensions; None otherwise.
pub fn name_tracks(
    tracks: &[Vector3<f64>],
    fixed: &[Option<usize>],
    approx: &[Vector3<f64>],
    opts: &NamingOptions,
) -> Option<Naming> {
    let seeded: Vec<(Vector3<f64>, Vector3<f64>)> = fixed
        .iter()
        .enumerate()
        .filter_map(|(k, f)| f.map(|j| (tracks[k], approx[j])))
        .collect();
    let spacing = median_spacing(approx);
    // start in the face's plane, where 3 seeds fix the map whatever their depths, then in 3-D
    let first =
        first_map_in_plane(tracks, fixed, approx, spacing).or_else(|| fit_affine(&seeded))?;
    let (map, mut sigma) = refine_map(
        tracks,
        fixed,
        approx,
        first,
        (0.5 * spacing).max(opts.min_sigma_m),
        opts,
    );
    let (pred, cost) = predictions_and_costs(tracks, &map, approx);
    let names = assign(&cost, fixed, approx.len(), (5.0 * sigma).powi(2));
    // The assignment picks the nearest approximations, so the scatter of the assigned pairs is biased
    // low when the approximations are rough; the seeds' scatter is not (their names are known).
    let seeded = fixed.iter().flatten().count();
    let seed_ss: f64 = (0..tracks.len())
        .filter_map(|k| fixed[k].map(|j| cost[k][j]))
        .sum();
    if seeded > 0 {
        sigma = sigma.max((seed_ss / (3 * seeded) as f64).sqrt());
    }
    // the targets' spacing as the images show it (the approximations' own is blurred by their
    // errors)
    let spacing_m = median_spacing(&pred);
    let max_sigma_m = opts.max_sigma_per_spacing * spacing_m;
    let (out, ambiguous, unlisted) =
        leave_out_doubtful(&names, fixed, &pred, &cost, (sigma, max_sigma_m), opts);
    Some(Naming {
        names: out,
        ambiguous,
        unlisted,
        sigma_m: sigma,
        spacing_m,
        max_sigma_m,
        map,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    /// A 6 × 4 grid 0.8 m apart with 1 m relief, seen in an affine frame (a shear and scale of the site).
    fn scene() -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let site: Vec<Vector3<f64>> = (0..24)
            .map(|k| {
                let (c, r) = ((k % 6) as f64, (k / 6) as f64);
                Vector3::new(0.8 * c, 0.8 * r, ((k * 5) % 7) as f64 / 7.0)
            })
            .collect();
        let a = nalgebra::Matrix3::new(0.3, 0.1, -0.2, 0.0, 0.4, 0.1, 0.05, -0.1, 0.9);
        let frame = site
            .iter()
            .map(|x| a * x + Vector3::new(1.0, 2.0, 3.0))
            .collect();
        (site, frame)
    }

    fn noisy(site: &[Vector3<f64>], sigma: f64, shift: f64, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut g = || rng.sample::<f64, _>(StandardNormal);
        let s = Vector3::new(shift, -0.5 * shift, 0.3 * shift);
        site.iter()
            .map(|x| x + s + sigma * Vector3::new(g(), g(), g()))
            .collect()
    }

    fn seeds(n: usize) -> Vec<Option<usize>> {
        (0..n)
            .map(|k| [0, 5, 18, 23].contains(&k).then_some(k))
            .collect()
    }

    #[test]
    fn a_map_shifted_as_a_whole_names_every_target() {
        let (site, frame) = scene();
        for seed in 0..10 {
            let approx = noisy(&site, 0.05, 0.6, seed);
            let n = name_tracks(&frame, &seeds(24), &approx, &NamingOptions::default()).unwrap();
            for (k, name) in n.names.iter().enumerate() {
                assert_eq!(*name, Some(k), "seed {seed}: {n:?}");
            }
            assert!(n.sigma_m < 0.08, "{}", n.sigma_m);
            // the grid's own spacing (0.8 m apart, with relief) as the tracks show it through the
            // map fitted to the approximations (within 7 %)
            let truth = median_spacing(&site);
            assert!(
                (n.spacing_m - truth).abs() < 0.06,
                "{} vs {truth}",
                n.spacing_m
            );
        }
    }

    #[test]
    fn rough_approximations_leave_targets_out_but_never_name_wrongly() {
        let (site, frame) = scene();
        let (mut named, mut total) = (0, 0);
        for seed in 0..20 {
            let approx = noisy(&site, 0.2, 0.0, 100 + seed);
            let n = name_tracks(&frame, &seeds(24), &approx, &NamingOptions::default()).unwrap();
            for (k, name) in n.names.iter().enumerate() {
                assert!(
                    name.is_none() || *name == Some(k),
                    "seed {seed}: track {k} named {name:?} σ {} {:?}",
                    n.sigma_m,
                    n.ambiguous
                );
                named += name.is_some() as usize;
                total += 1;
            }
            assert_eq!(
                n.names.iter().filter(|x| x.is_none()).count(),
                n.ambiguous.len() + n.unlisted.len()
            );
        }
        eprintln!("named {named} of {total}");
        // about half of the targets, spaced 0.8 m, carry a clear name at σ 0.2 m
        assert!(named * 4 > total, "{named} of {total}");
    }

    /// Approximations scattered by more than 0.3 × the spacing name no target, whatever the
    /// margins say.
    #[test]
    fn approximations_as_rough_as_a_third_of_the_spacing_name_nothing() {
        let (site, frame) = scene();
        for seed in 0..10 {
            let approx = noisy(&site, 0.4, 0.0, 200 + seed);
            let n = name_tracks(&frame, &seeds(24), &approx, &NamingOptions::default()).unwrap();
            let spacing = n.spacing_m;
            assert!(
                n.sigma_m > 0.3 * spacing,
                "seed {seed}: σ {} spacing {spacing}",
                n.sigma_m
            );
            let named: Vec<usize> = (0..24).filter(|&k| n.names[k].is_some()).collect();
            assert_eq!(named, vec![0, 5, 18, 23], "seed {seed}: only the seeds");
            assert_eq!(n.ambiguous.len() + n.unlisted.len(), 20, "seed {seed}");
        }
    }
}
