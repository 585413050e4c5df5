//! 8-connected components of threshold runs, with binary moments.

use super::threshold::Run;

/// A connected foreground region: pixel count, bounding box and binary moments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Pixel count.
    pub area: f64,
    /// Mean column of the pixels (px).
    pub col: f64,
    /// Mean row of the pixels (px).
    pub row: f64,
    /// Central second moments (px²): [μxx, μyy, μxy].
    pub m2: [f64; 3],
    /// Bounding box [col_min, row_min, col_max, row_max] (inclusive).
    pub bbox: [u32; 4],
}

impl Component {
    /// Ratio of the axes of the moment ellipse (≥ 1).
    pub fn aspect(&self) -> f64 {
        let (l1, l2) = self.eigen();
        (l1 / l2.max(1e-9)).sqrt()
    }
    /// Area over the area of the moment ellipse (1 for a filled ellipse).
    pub fn fill(&self) -> f64 {
        let (l1, l2) = self.eigen();
        self.area / (4.0 * std::f64::consts::PI * (l1 * l2).sqrt().max(1e-9))
    }
    fn eigen(&self) -> (f64, f64) {
        let [a, b, c] = self.m2;
        let m = 0.5 * (a + b);
        let d = (0.25 * (a - b) * (a - b) + c * c).sqrt();
        (m + d, (m - d).max(0.0))
    }
}

fn find(p: &mut [u32], mut i: u32) -> u32 {
    while p[i as usize] != i {
        p[i as usize] = p[p[i as usize] as usize];
        i = p[i as usize];
    }
    i
}

/// Groups row-ordered runs into 8-connected components.
pub fn components(runs: &[Run]) -> Vec<Component> {
    let n = runs.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut prev = 0..0;
    let mut i = 0;
    while i < n {
        let row = runs[i].row;
        let mut j = i;
        while j < n && runs[j].row == row {
            j += 1;
        }
        let prev_ok = prev.end > prev.start && runs[prev.start].row + 1 == row;
        if prev_ok {
            let mut a = prev.start;
            for b in i..j {
                while a < prev.end && runs[a].x1 < runs[b].x0 {
                    a += 1;
                }
                let mut k = a;
                while k < prev.end && runs[k].x0 <= runs[b].x1 {
                    let (ra, rb) = (find(&mut parent, k as u32), find(&mut parent, b as u32));
                    if ra != rb {
                        parent[ra.max(rb) as usize] = ra.min(rb);
                    }
                    k += 1;
                }
            }
        }
        prev = i..j;
        i = j;
    }
    // accumulate [n, Σx, Σy, Σx², Σy², Σxy] and bbox per root
    let mut acc: std::collections::HashMap<u32, ([f64; 6], [u32; 4])> = Default::default();
    for (k, r) in runs.iter().enumerate() {
        let root = find(&mut parent, k as u32);
        let (x0, x1, y) = (r.x0 as f64, r.x1 as f64 - 1.0, r.row as f64);
        let len = x1 - x0 + 1.0;
        let s1 = (x0 + x1) * len / 2.0;
        let s2 = |m: f64| m * (m + 1.0) * (2.0 * m + 1.0) / 6.0;
        let sx2 = s2(x1) - s2(x0 - 1.0);
        let e = acc
            .entry(root)
            .or_insert(([0.0; 6], [u32::MAX, u32::MAX, 0, 0]));
        e.0[0] += len;
        e.0[1] += s1;
        e.0[2] += y * len;
        e.0[3] += sx2;
        e.0[4] += y * y * len;
        e.0[5] += y * s1;
        e.1 = [
            e.1[0].min(r.x0),
            e.1[1].min(r.row),
            e.1[2].max(r.x1 - 1),
            e.1[3].max(r.row),
        ];
    }
    let mut out: Vec<Component> = acc
        .into_values()
        .map(|(s, bbox)| {
            let (cx, cy) = (s[1] / s[0], s[2] / s[0]);
            Component {
                area: s[0],
                col: cx,
                row: cy,
                m2: [
                    s[3] / s[0] - cx * cx + 1.0 / 12.0,
                    s[4] / s[0] - cy * cy + 1.0 / 12.0,
                    s[5] / s[0] - cx * cy,
                ],
                bbox,
            }
        })
        .collect();
    out.sort_by(|a, b| {
        (a.row, a.col)
            .partial_cmp(&(b.row, b.col))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    out
}
