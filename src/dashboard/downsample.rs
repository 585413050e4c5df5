//! Which epochs of a long series a plot draws (pure, no I/O).
//!
//! A plot `width` pixels wide cannot show more than a few values per pixel column, so the plot
//! endpoints send at most about `2 × width` epochs: the series is cut into `width / 4` buckets of
//! consecutive epochs, and each bucket keeps the epochs where each column (dx, dy, dz, d, …) has
//! its minimum and its maximum ("min/max per bucket", as time-series databases do). Peaks are
//! never flattened. The first and the last epoch, and every epoch flagged (an alert epoch), are
//! always kept.

/// Indices (ascending, without repeats) of the epochs a plot `width` pixels wide draws.
///
/// `columns`: the values per epoch whose extremes must survive (each as long as the series; NaN
/// for a missing value). `keep`: indices that must be kept whatever they hold (alert epochs);
/// indices out of range are ignored. With `n ≤ 2 × width` every index is returned.
pub fn plot_indices(n: usize, columns: &[&[f64]], keep: &[usize], width: usize) -> Vec<usize> {
    let width = width.max(8);
    if n <= 2 * width {
        return (0..n).collect();
    }
    let buckets = (width / 4).max(1);
    let mut out = Vec::with_capacity(2 * width + keep.len() + 2);
    out.push(0);
    out.push(n - 1);
    out.extend(keep.iter().copied().filter(|&i| i < n));
    for b in 0..buckets {
        let (lo, hi) = (b * n / buckets, (b + 1) * n / buckets);
        if lo >= hi {
            continue;
        }
        for col in columns {
            let slice = &col[lo..hi.min(col.len())];
            let mut min: Option<(usize, f64)> = None;
            let mut max: Option<(usize, f64)> = None;
            for (k, &v) in slice.iter().enumerate() {
                if !v.is_finite() {
                    continue;
                }
                if min.is_none_or(|m| v < m.1) {
                    min = Some((k, v));
                }
                if max.is_none_or(|m| v > m.1) {
                    max = Some((k, v));
                }
            }
            out.extend(min.map(|m| lo + m.0));
            out.extend(max.map(|m| lo + m.0));
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn short_series_is_kept_whole() {
        let v: Vec<f64> = (0..40).map(f64::from).collect();
        assert_eq!(
            plot_indices(40, &[&v], &[], 800),
            (0..40).collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_single_spike_survives() {
        let mut v = vec![0.0; 87_600];
        v[43_210] = 9.0;
        v[12_345] = -4.0;
        let idx = plot_indices(v.len(), &[&v], &[], 800);
        assert!(idx.len() <= 1600, "{} indices", idx.len());
        assert!(idx.contains(&43_210) && idx.contains(&12_345));
        assert_eq!((idx[0], *idx.last().unwrap()), (0, 87_599));
    }

    proptest! {
        /// Every bucket's extremes survive, so the drawn range of each column is the full
        /// series' range; the first, last and flagged epochs are kept; at most 2 × width plus
        /// the flagged and end epochs are returned.
        #[test]
        fn extremes_ends_and_flags_survive(
            a in prop::collection::vec(-1e3f64..1e3, 1..5000),
            width in 8usize..400,
            flag in 0usize..6000,
        ) {
            let b: Vec<f64> = a.iter().map(|x| (x * 0.37).sin()).collect();
            let n = a.len();
            let idx = plot_indices(n, &[&a, &b], &[flag], width);
            prop_assert!(idx.windows(2).all(|w| w[0] < w[1]));
            prop_assert!(idx.len() <= 2 * width.max(8) + 3);
            prop_assert_eq!(idx[0], 0);
            prop_assert_eq!(*idx.last().unwrap(), n - 1);
            if flag < n {
                prop_assert!(idx.contains(&flag));
            }
            for col in [&a, &b] {
                let full_max = col.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let full_min = col.iter().copied().fold(f64::INFINITY, f64::min);
                let kept_max = idx.iter().map(|&i| col[i]).fold(f64::NEG_INFINITY, f64::max);
                let kept_min = idx.iter().map(|&i| col[i]).fold(f64::INFINITY, f64::min);
                prop_assert_eq!(full_max, kept_max);
                prop_assert_eq!(full_min, kept_min);
            }
        }
    }
}
