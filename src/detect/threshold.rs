//! Adaptive threshold: a coarse robust background grid, a global noise figure, and runs of
//! foreground pixels (signal above background by a multiple of the noise).

use super::decode::GreyImage;
use super::target::Polarity;
use rayon::prelude::*;

/// Background model: per-cell medians on a grid, interpolated bilinearly between cell centres, and
/// the image noise σ in grey levels.
#[derive(Debug, Clone)]
pub struct Background {
    cell: usize,
    gw: usize,
    gh: usize,
    level: Vec<f32>,
    /// Noise σ in grey levels (from neighbouring-pixel differences, robust).
    pub noise: f64,
}

/// A horizontal run of foreground pixels: `row`, columns `x0..x1` (end exclusive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// Row of the run.
    pub row: u32,
    /// First column.
    pub x0: u32,
    /// One past the last column.
    pub x1: u32,
}

fn median(v: &mut [u16]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let m = v.len() / 2;
    *v.select_nth_unstable(m).1 as f32
}

/// Estimates the background on cells of `cell` px (robust median of a subsample) and the noise σ.
pub fn estimate_background(img: &GreyImage, cell: usize) -> Background {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let cell = cell.max(8);
    let gw = w.div_ceil(cell);
    let gh = h.div_ceil(cell);
    let step = (cell / 32).max(1);
    let stats: Vec<(f32, f32)> = (0..gw * gh)
        .into_par_iter()
        .map(|k| {
            let (gx, gy) = (k % gw, k / gw);
            let (x0, y0) = (gx * cell, gy * cell);
            let (x1, y1) = ((x0 + cell).min(w), (y0 + cell).min(h));
            let mut vals = Vec::with_capacity(1100);
            let mut diffs = Vec::with_capacity(1100);
            for y in (y0..y1).step_by(step) {
                for x in (x0..x1).step_by(step) {
                    let v = img.get(x, y);
                    vals.push(v);
                    if x + 1 < w {
                        diffs.push(v.abs_diff(img.get(x + 1, y)));
                    }
                }
            }
            (median(&mut vals), median(&mut diffs))
        })
        .collect();
    let level = stats.iter().map(|s| s.0).collect();
    let mut d: Vec<f32> = stats.iter().map(|s| s.1).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    // median |difference| of two N(0, σ) values is 0.6745·√2·σ
    let noise = (d[d.len() / 2] as f64 * 1.0484).max(0.5);
    Background {
        cell,
        gw,
        gh,
        level,
        noise,
    }
}

impl Background {
    /// Interpolated background level (grey levels) at (col, row).
    pub fn at(&self, col: f64, row: f64) -> f64 {
        let (j0, tx) = self.coord(col, self.gw);
        let (i0, ty) = self.coord(row, self.gh);
        let j1 = (j0 + 1).min(self.gw - 1);
        let i1 = (i0 + 1).min(self.gh - 1);
        let l = |i: usize, j: usize| self.level[i * self.gw + j] as f64;
        (l(i0, j0) * (1.0 - tx) + l(i0, j1) * tx) * (1.0 - ty)
            + (l(i1, j0) * (1.0 - tx) + l(i1, j1) * tx) * ty
    }

    fn coord(&self, p: f64, n: usize) -> (usize, f64) {
        let f = ((p + 0.5) / self.cell as f64 - 0.5).clamp(0.0, (n - 1) as f64);
        let i = (f.floor() as usize).min(n - 1);
        (i, f - i as f64)
    }
}

/// Runs of pixels whose signal (`polarity`-signed difference to the background) exceeds
/// `threshold` grey levels, in row order.
pub fn threshold_runs(
    img: &GreyImage,
    bg: &Background,
    polarity: Polarity,
    threshold: f64,
) -> Vec<Run> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let sign = polarity.sign() as f32;
    let t = threshold as f32;
    let cols: Vec<(usize, f32)> = (0..w)
        .map(|x| {
            let (j, tx) = bg.coord(x as f64, bg.gw);
            (j, tx as f32)
        })
        .collect();
    // segments of columns between neighbouring cell centres (one interpolation interval each)
    let mut segs: Vec<(usize, usize)> = Vec::new();
    for x in 0..w {
        match segs.last_mut() {
            Some(last) if cols[last.0].0 == cols[x].0 => last.1 = x + 1,
            _ => segs.push((x, x + 1)),
        }
    }
    let rows: Vec<Vec<Run>> = (0..h)
        .into_par_iter()
        .with_min_len(16)
        .map(|y| {
            let (i0, ty) = bg.coord(y as f64, bg.gh);
            let i1 = (i0 + 1).min(bg.gh - 1);
            let ty = ty as f32;
            let g: Vec<f32> = (0..bg.gw + 1)
                .map(|j| {
                    let j = j.min(bg.gw - 1);
                    bg.level[i0 * bg.gw + j] * (1.0 - ty) + bg.level[i1 * bg.gw + j] * ty
                })
                .collect();
            let line = &img.data()[y * w..(y + 1) * w];
            let bg_at = |x: usize| {
                let (j, tx) = cols[x];
                g[j] + (g[j + 1] - g[j]) * tx
            };
            let mut runs = Vec::new();
            let mut start: Option<usize> = None;
            for &(xs, xe) in &segs {
                // the background is linear (monotone) over a segment: when even the extreme pixel is
                // not foreground against the extreme background, no pixel of the segment is
                let (b0, b1) = (bg_at(xs), bg_at(xe - 1));
                let seg = &line[xs..xe];
                let clear = match polarity {
                    Polarity::BrightOnDark => {
                        let vmax = seg.iter().copied().max().unwrap_or(0) as f32;
                        vmax - b0.min(b1) <= t
                    }
                    Polarity::DarkOnBright => {
                        let vmin = seg.iter().copied().min().unwrap_or(0) as f32;
                        b0.max(b1) - vmin <= t
                    }
                };
                if clear {
                    if let Some(s) = start.take() {
                        runs.push(Run {
                            row: y as u32,
                            x0: s as u32,
                            x1: xs as u32,
                        });
                    }
                    continue;
                }
                for (x, &v) in (xs..xe).zip(seg) {
                    let fg = sign * (v as f32 - bg_at(x)) > t;
                    match (fg, start) {
                        (true, None) => start = Some(x),
                        (false, Some(s)) => {
                            runs.push(Run {
                                row: y as u32,
                                x0: s as u32,
                                x1: x as u32,
                            });
                            start = None;
                        }
                        _ => {}
                    }
                }
            }
            if let Some(s) = start {
                runs.push(Run {
                    row: y as u32,
                    x0: s as u32,
                    x1: w as u32,
                });
            }
            runs
        })
        .collect();
    rows.into_iter().flatten().collect()
}
