//! Adaptive threshold from local contrast: a coarse robust background grid with each cell's
//! darkest and brightest pixel, a global noise figure, threshold levels a fixed share of the way
//! from the background to the local extreme (never closer to the background than a multiple of the
//! noise), and runs of foreground pixels beyond them.

use super::decode::GreyImage;
use super::target::Polarity;
use rayon::prelude::*;

/// Background model: per-cell medians, darkest and brightest levels on a grid, interpolated
/// bilinearly between cell centres, and the image noise σ in grey levels.
#[derive(Debug, Clone)]
pub struct Background {
    cell: usize,
    gw: usize,
    gh: usize,
    level: Vec<f32>,
    lo: Vec<f32>,
    hi: Vec<f32>,
    /// Noise σ in grey levels: the median over cells of the median absolute difference of
    /// horizontal neighbours (interpolated within its integer step, so that the smooth noise of a
    /// JPEG is not rounded to 0 or 1), scaled to σ; robust to edges, no floor.
    pub noise: f64,
}

/// Threshold levels on the background grid for one polarity (grey levels, interpolated like the
/// background): a pixel is foreground when it lies beyond the level, on the polarity's side.
#[derive(Debug, Clone)]
pub struct Levels {
    cell: usize,
    gw: usize,
    gh: usize,
    level: Vec<f32>,
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

/// The median of integer values, interpolated within the step holding it (values spread evenly
/// over [k − ½, k + ½), and over [0, ½) for 0, as absolute differences of integers are).
fn interpolated_median(v: &mut [u16]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let half = v.len() as f32 / 2.0;
    let m = *v.select_nth_unstable(v.len() / 2).1;
    let below = v.iter().filter(|&&x| x < m).count() as f32;
    let equal = v.iter().filter(|&&x| x == m).count() as f32;
    let (start, width) = if m == 0 {
        (0.0, 0.5)
    } else {
        (m as f32 - 0.5, 1.0)
    };
    start + width * ((half - below) / equal).clamp(0.0, 1.0)
}

/// Estimates the background on cells of `cell` px (robust median of a subsample), each cell's
/// darkest and brightest pixel (all pixels) and the noise σ.
pub fn estimate_background(img: &GreyImage, cell: usize) -> Background {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let cell = cell.max(8);
    let gw = w.div_ceil(cell);
    let gh = h.div_ceil(cell);
    let step = (cell / 32).max(1);
    let stats: Vec<[f32; 4]> = (0..gw * gh)
        .into_par_iter()
        .map(|k| {
            let (gx, gy) = (k % gw, k / gw);
            let (x0, y0) = (gx * cell, gy * cell);
            let (x1, y1) = ((x0 + cell).min(w), (y0 + cell).min(h));
            let mut vals = Vec::with_capacity(1100);
            let mut diffs = Vec::with_capacity(1100);
            let (mut lo, mut hi) = (u16::MAX, 0u16);
            for y in y0..y1 {
                let line = &img.data()[y * w + x0..y * w + x1];
                for &v in line {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                if (y - y0) % step == 0 {
                    vals.extend(line.iter().step_by(step));
                    diffs.extend(line.windows(2).step_by(step).map(|p| p[0].abs_diff(p[1])));
                }
            }
            let med = median(&mut vals);
            [med, lo as f32, hi as f32, interpolated_median(&mut diffs)]
        })
        .collect();
    let level = stats.iter().map(|s| s[0]).collect();
    let lo = stats.iter().map(|s| s[1]).collect();
    let hi = stats.iter().map(|s| s[2]).collect();
    let mut d: Vec<f32> = stats.iter().map(|s| s[3]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    // median |difference| of two N(0, σ) values is 0.6745·√2·σ
    let noise = d[d.len() / 2] as f64 * 1.0484;
    Background {
        cell,
        gw,
        gh,
        level,
        lo,
        hi,
        noise,
    }
}

impl Background {
    /// Interpolated background level (grey levels) at (col, row).
    pub fn at(&self, col: f64, row: f64) -> f64 {
        let (j0, tx) = coord(self.cell, col, self.gw);
        let (i0, ty) = coord(self.cell, row, self.gh);
        let j1 = (j0 + 1).min(self.gw - 1);
        let i1 = (i0 + 1).min(self.gh - 1);
        let l = |i: usize, j: usize| self.level[i * self.gw + j] as f64;
        (l(i0, j0) * (1.0 - tx) + l(i0, j1) * tx) * (1.0 - ty)
            + (l(i1, j0) * (1.0 - tx) + l(i1, j1) * tx) * ty
    }

    /// Threshold levels from the local contrast: in each cell, `fraction` of the way from the
    /// background to the most extreme pixel (on the polarity's side) of the cell and its eight
    /// neighbours, and at least `min_offset` grey levels from the background. A target is then cut
    /// at a fixed share of the local contrast whatever the lighting (a fraction below one half
    /// keeps a grey target beside a black one), and a cell of paper or sky holds no foreground.
    pub fn levels(&self, polarity: Polarity, fraction: f64, min_offset: f64) -> Levels {
        let ext = match polarity {
            Polarity::BrightOnDark => &self.hi,
            Polarity::DarkOnBright => &self.lo,
        };
        let sign = polarity.sign() as f32;
        let min_offset = min_offset as f32;
        let fraction = fraction as f32;
        let mut level = vec![0.0f32; self.gw * self.gh];
        for i in 0..self.gh {
            for j in 0..self.gw {
                let b = self.level[i * self.gw + j];
                let mut c = 0.0f32;
                for ii in i.saturating_sub(1)..=(i + 1).min(self.gh - 1) {
                    for jj in j.saturating_sub(1)..=(j + 1).min(self.gw - 1) {
                        c = c.max(sign * (ext[ii * self.gw + jj] - b));
                    }
                }
                level[i * self.gw + j] = b + sign * (fraction * c).max(min_offset);
            }
        }
        Levels {
            cell: self.cell,
            gw: self.gw,
            gh: self.gh,
            level,
        }
    }
}

fn coord(cell: usize, p: f64, n: usize) -> (usize, f64) {
    let f = ((p + 0.5) / cell as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let i = (f.floor() as usize).min(n - 1);
    (i, f - i as f64)
}

/// Runs of pixels beyond the threshold `levels` on the `polarity`'s side (brighter for
/// bright-on-dark, darker for dark-on-bright), in row order.
pub fn threshold_runs(img: &GreyImage, levels: &Levels, polarity: Polarity) -> Vec<Run> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let sign = polarity.sign() as f32;
    let lv = levels;
    let cols: Vec<(usize, f32)> = (0..w)
        .map(|x| {
            let (j, tx) = coord(lv.cell, x as f64, lv.gw);
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
            let (i0, ty) = coord(lv.cell, y as f64, lv.gh);
            let i1 = (i0 + 1).min(lv.gh - 1);
            let ty = ty as f32;
            let g: Vec<f32> = (0..lv.gw + 1)
                .map(|j| {
                    let j = j.min(lv.gw - 1);
                    lv.level[i0 * lv.gw + j] * (1.0 - ty) + lv.level[i1 * lv.gw + j] * ty
                })
                .collect();
            let line = &img.data()[y * w..(y + 1) * w];
            let lv_at = |x: usize| {
                let (j, tx) = cols[x];
                g[j] + (g[j + 1] - g[j]) * tx
            };
            let mut runs = Vec::new();
            let mut start: Option<usize> = None;
            for &(xs, xe) in &segs {
                // the level is linear (monotone) over a segment: when even the extreme pixel is
                // not beyond the extreme level, no pixel of the segment is
                let (l0, l1) = (lv_at(xs), lv_at(xe - 1));
                let seg = &line[xs..xe];
                let clear = match polarity {
                    Polarity::BrightOnDark => {
                        let vmax = seg.iter().copied().max().unwrap_or(0) as f32;
                        vmax <= l0.min(l1)
                    }
                    Polarity::DarkOnBright => {
                        let vmin = seg.iter().copied().min().unwrap_or(0) as f32;
                        vmin >= l0.max(l1)
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
                    let fg = sign * (v as f32 - lv_at(x)) > 0.0;
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
