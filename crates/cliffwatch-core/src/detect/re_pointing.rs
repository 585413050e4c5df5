//! A station set up again or re-aimed since its last epoch (pure): the whole pattern of targets
//! moves on the image by more than the matching gates, so no projection finds its detection. The
//! shift is found by voting: every pairing of a projection with a detection proposes a translation,
//! and the one that brings the most projections within their gate of a detection wins, if it wins
//! clearly. A pattern with another translation nearly as good (a regular grid shifted by one
//! spacing) gives none: names are never guessed.

use std::collections::HashMap;

/// Fewest projections a translation must bring onto detections to be accepted.
pub(crate) const MIN_VOTES: usize = 4;

/// The translation (image mm) that brings the most projections `proj` (position, gate radius in
/// mm) within their gate of a detection `blobs` (mm), refined to the mean offset of those pairs;
/// `None` unless it gathers at least [`MIN_VOTES`] and twice the votes of any translation more than
/// two gates away from it.
pub(crate) fn translation_by_votes(
    proj: &[([f64; 2], f64)],
    blobs: &[[f64; 2]],
) -> Option<[f64; 2]> {
    let cell = proj.iter().map(|p| p.1).fold(0.0, f64::max);
    if !(cell > 0.0 && cell.is_finite()) || blobs.is_empty() {
        return None;
    }
    let grid = Grid::new(blobs, cell);
    let mut tallies: Vec<([f64; 2], usize)> = Vec::with_capacity(proj.len() * blobs.len());
    for (q, _) in proj {
        for b in blobs {
            let t = [b[0] - q[0], b[1] - q[1]];
            tallies.push((t, grid.votes(proj, t).0));
        }
    }
    let &(t0, _) = tallies.iter().max_by_key(|(_, n)| *n)?;
    // refine to the mean offset of the pairs the winner gathered, and count again
    let (_, offset) = grid.votes(proj, t0);
    let best = [t0[0] + offset[0], t0[1] + offset[1]];
    let (n_best, _) = grid.votes(proj, best);
    let rival = tallies
        .iter()
        .filter(|(t, _)| (t[0] - best[0]).hypot(t[1] - best[1]) > 2.0 * cell)
        .map(|(_, n)| *n)
        .max()
        .unwrap_or(0);
    (n_best >= MIN_VOTES && n_best >= 2 * rival).then_some(best)
}

/// The detections in square cells of the largest gate, for the neighbours of a position.
struct Grid<'a> {
    blobs: &'a [[f64; 2]],
    cell: f64,
    cells: HashMap<(i64, i64), Vec<usize>>,
}

impl<'a> Grid<'a> {
    fn new(blobs: &'a [[f64; 2]], cell: f64) -> Self {
        let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for (j, b) in blobs.iter().enumerate() {
            cells.entry(Self::key(b, cell)).or_default().push(j);
        }
        Grid { blobs, cell, cells }
    }

    fn key(p: &[f64; 2], cell: f64) -> (i64, i64) {
        ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64)
    }

    /// The nearest detection within `gate` of `p`, as its offset from `p`.
    fn nearest(&self, p: [f64; 2], gate: f64) -> Option<[f64; 2]> {
        let (cx, cy) = Self::key(&p, self.cell);
        let mut best: Option<(f64, [f64; 2])> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &j in self.cells.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                    let o = [self.blobs[j][0] - p[0], self.blobs[j][1] - p[1]];
                    let d = o[0].hypot(o[1]);
                    if d <= gate && best.is_none_or(|(e, _)| d < e) {
                        best = Some((d, o));
                    }
                }
            }
        }
        best.map(|(_, o)| o)
    }

    /// How many projections shifted by `t` have a detection within their gate, and the mean
    /// offset from them to those detections.
    fn votes(&self, proj: &[([f64; 2], f64)], t: [f64; 2]) -> (usize, [f64; 2]) {
        let (mut n, mut sum) = (0usize, [0.0, 0.0]);
        for (q, g) in proj {
            if let Some(o) = self.nearest([q[0] + t[0], q[1] + t[1]], *g) {
                n += 1;
                sum[0] += o[0];
                sum[1] += o[1];
            }
        }
        let mean = if n > 0 {
            [sum[0] / n as f64, sum[1] / n as f64]
        } else {
            [0.0, 0.0]
        };
        (n, mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// An irregular pattern of `n` targets over ±10 mm, gates of 0.2 mm.
    fn pattern(n: usize, seed: u64) -> Vec<([f64; 2], f64)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| ([rng.gen_range(-10.0..10.0), rng.gen_range(-7.0..7.0)], 0.2))
            .collect()
    }

    #[test]
    fn finds_the_shift_of_a_re_aimed_station_over_seeds() {
        for seed in 0..20 {
            let proj = pattern(28, seed);
            let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
            let t = [rng.gen_range(-4.0..4.0), rng.gen_range(-3.0..3.0)];
            // the shifted pattern, with noise; some targets left the view; two glints
            let mut blobs: Vec<[f64; 2]> = proj
                .iter()
                .map(|(q, _)| {
                    [
                        q[0] + t[0] + rng.gen_range(-0.05..0.05),
                        q[1] + t[1] + rng.gen_range(-0.05..0.05),
                    ]
                })
                .filter(|b| b[0].abs() < 10.0 && b[1].abs() < 7.0)
                .collect();
            blobs.push([3.3, -2.2]);
            blobs.push([-8.1, 5.0]);
            let found = translation_by_votes(&proj, &blobs).expect("a shift");
            assert!(
                (found[0] - t[0]).hypot(found[1] - t[1]) < 0.05,
                "seed {seed}: {found:?} against {t:?}"
            );
        }
    }

    #[test]
    fn a_regular_grid_shifted_by_its_spacing_gives_no_shift() {
        // a 7 × 4 grid of 3 mm spacing seen shifted by exactly one spacing: the shift by 0, by
        // one and by two spacings all gather most targets, so none is accepted
        let proj: Vec<([f64; 2], f64)> = (0..28)
            .map(|k| {
                (
                    [3.0 * (k % 7) as f64 - 9.0, 3.0 * (k / 7) as f64 - 4.5],
                    0.2,
                )
            })
            .collect();
        let blobs: Vec<[f64; 2]> = proj.iter().map(|(q, _)| [q[0] + 3.0, q[1]]).collect();
        assert_eq!(translation_by_votes(&proj, &blobs), None);
    }

    #[test]
    fn too_few_or_no_detections_give_no_shift() {
        let proj = pattern(28, 1);
        assert_eq!(translation_by_votes(&proj, &[]), None);
        let three: Vec<[f64; 2]> = proj[..3].iter().map(|(q, _)| [q[0] + 1.0, q[1]]).collect();
        assert_eq!(translation_by_votes(&proj, &three), None);
    }
}
