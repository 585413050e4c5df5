//! Which epochs of a long series a plot draws (pure, no I/O).
//!
//! A plot `width` pixels wide cannot show more than a few values per pixel column, so the plot
//! endpoints send at most about `2 × width` epochs: the series is cut into `width / 4` buckets of
//! consecutive epochs, and each bucket keeps the epochs where each column (dx, dy, dz, d, …) has
//! its minimum and its maximum ("min/max per bucket", as time-series databases do). Peaks are
//! never flattened. The first and the last epoch, and every epoch flagged (an alert epoch), are
//! always kept.
//!
//! [`plot_indices`] works on columns held whole; [`PlotPicker`] takes the same decision one epoch
//! at a time, keeping only the rows it may still draw, so a 10-year hourly series is never held
//! in memory (allocating and touching tens of megabytes cost more than reading the series).

/// Buckets of a plot `width` pixels wide: each keeps up to two epochs per column, so about four
/// pixels per bucket.
pub fn bucket_count(width: usize) -> usize {
    (width.max(8) / 4).max(1)
}

/// Indices (ascending, without repeats) of the epochs a plot `width` pixels wide draws.
///
/// `columns`: the values per epoch whose extremes must survive (each as long as the series; NaN
/// for a missing value). `keep`: indices that must be kept whatever they hold (alert epochs);
/// indices out of range are ignored. With `n ≤ 2 × width` every index is returned.
pub fn plot_indices(n: usize, columns: &[&[f64]], keep: &[usize], width: usize) -> Vec<usize> {
    let buckets = bucket_count(width);
    let width = width.max(8);
    if n <= 2 * width {
        return (0..n).collect();
    }
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

/// The streaming form of [`plot_indices`]: fed the epochs in order (their values, whether they
/// are flagged, and the row to keep), it holds only the current bucket's candidates and the rows
/// already chosen. With the series' length `n` known in advance it keeps exactly the rows
/// [`plot_indices`] would; epochs beyond `n` (written while the series was read) fall into the
/// last bucket, and the last epoch fed is always kept.
#[derive(Debug)]
pub struct PlotPicker<R> {
    n: usize,
    buckets: usize,
    whole: bool,
    next: usize,
    bucket: usize,
    bucket_end: usize,
    /// Per column: (index, value) of the bucket's minimum and maximum so far.
    extremes: Vec<[Option<(usize, f64)>; 2]>,
    /// Indices of the bucket that must be kept (flagged, or the first epoch).
    forced: Vec<usize>,
    /// Rows of the bucket that were an extreme when fed, or forced.
    pending: Vec<(usize, R)>,
    kept: Vec<(usize, R)>,
    last: Option<(usize, R)>,
}

impl<R: Clone> PlotPicker<R> {
    /// A picker for a series of `n` epochs with `columns` values each, drawn `width` px wide.
    pub fn new(n: usize, columns: usize, width: usize) -> Self {
        let buckets = bucket_count(width);
        let width = width.max(8);
        PlotPicker {
            n,
            buckets,
            whole: n <= 2 * width,
            next: 0,
            bucket: 0,
            bucket_end: n / buckets,
            extremes: vec![[None; 2]; columns],
            forced: Vec::new(),
            pending: Vec::new(),
            kept: Vec::with_capacity(if n <= 2 * width { n } else { 2 * width + 2 }),
            last: None,
        }
    }

    /// Feeds the next epoch: its `values` (one per column, NaN when missing), whether it must be
    /// kept, and its row.
    pub fn push(&mut self, values: &[f64], flagged: bool, row: R) {
        let i = self.next;
        self.next += 1;
        if self.whole {
            self.kept.push((i, row));
            return;
        }
        while i >= self.bucket_end && self.bucket + 1 < self.buckets {
            self.close_bucket();
            self.bucket += 1;
            self.bucket_end = (self.bucket + 1) * self.n / self.buckets;
        }
        let mut candidate = false;
        if flagged || i == 0 {
            self.forced.push(i);
            candidate = true;
        }
        for (e, &v) in self.extremes.iter_mut().zip(values) {
            if !v.is_finite() {
                continue;
            }
            if e[0].is_none_or(|m| v < m.1) {
                e[0] = Some((i, v));
                candidate = true;
            }
            if e[1].is_none_or(|m| v > m.1) {
                e[1] = Some((i, v));
                candidate = true;
            }
        }
        if candidate {
            self.pending.push((i, row.clone()));
        }
        self.last = Some((i, row));
    }

    /// Moves the bucket's chosen rows (extremes and forced) to the kept ones.
    fn close_bucket(&mut self) {
        let chosen = |i: usize, extremes: &[[Option<(usize, f64)>; 2]], forced: &[usize]| {
            forced.contains(&i)
                || extremes
                    .iter()
                    .any(|e| e.iter().flatten().any(|&(k, _)| k == i))
        };
        for (i, row) in self.pending.drain(..) {
            if chosen(i, &self.extremes, &self.forced) {
                self.kept.push((i, row));
            }
        }
        self.forced.clear();
        for e in &mut self.extremes {
            *e = [None; 2];
        }
    }

    /// Epochs fed so far.
    pub fn fed(&self) -> usize {
        self.next
    }

    /// The rows to draw with their indices, in order.
    pub fn finish(mut self) -> Vec<(usize, R)> {
        if !self.whole {
            self.close_bucket();
            if let Some((i, row)) = self.last.take() {
                if self.kept.last().is_none_or(|k| k.0 != i) {
                    self.kept.push((i, row));
                }
            }
        }
        self.kept
    }
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

    /// Fed one epoch at a time, the picker keeps exactly what [`plot_indices`] keeps.
    fn picked(columns: &[&[f64]], flags: &[usize], width: usize, n_hint: usize) -> Vec<usize> {
        let n = columns[0].len();
        let mut p = PlotPicker::new(n_hint, columns.len(), width);
        for i in 0..n {
            let values: Vec<f64> = columns.iter().map(|c| c[i]).collect();
            p.push(&values, flags.contains(&i), i);
        }
        assert_eq!(p.fed(), n);
        let kept = p.finish();
        assert!(
            kept.iter().all(|(i, r)| i == r),
            "rows travel with their index"
        );
        kept.into_iter().map(|(i, _)| i).collect()
    }

    #[test]
    fn the_picker_keeps_the_long_series_spike() {
        let mut v = vec![0.0; 87_600];
        v[43_210] = 9.0;
        v[12_345] = -4.0;
        let idx = picked(&[&v], &[], 800, v.len());
        assert_eq!(idx, plot_indices(v.len(), &[&v], &[], 800));
        assert!(idx.contains(&43_210) && idx.contains(&12_345));
    }

    proptest! {
        /// The streaming picker and [`plot_indices`] agree when the length is known; with a
        /// length hint that is short by a few epochs (rows written during the read) every epoch
        /// still reaches the picker, the extremes and the ends survive, and the count stays
        /// bounded.
        #[test]
        fn picker_equals_plot_indices(
            a in prop::collection::vec(-1e3f64..1e3, 1..4000),
            width in 8usize..300,
            flag in 0usize..5000,
            short in 0usize..5,
        ) {
            let b: Vec<f64> = a.iter().map(|x| if *x > 900.0 { f64::NAN } else { (x * 0.37).sin() }).collect();
            let n = a.len();
            prop_assert_eq!(picked(&[&a, &b], &[flag], width, n), plot_indices(n, &[&a, &b], &[flag], width));
            let hinted = picked(&[&a, &b], &[flag], width, n.saturating_sub(short));
            prop_assert!(hinted.windows(2).all(|w| w[0] < w[1]));
            prop_assert_eq!(hinted[0], 0);
            prop_assert_eq!(*hinted.last().unwrap(), n - 1);
            prop_assert!(hinted.len() <= (2 * width.max(8) + 3).max(n.min(2 * width.max(8) + 5)));
            let max = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            prop_assert!(hinted.iter().any(|&i| a[i] == max));
        }

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
