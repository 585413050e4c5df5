//! Which names of the face plan to draw so that none overlaps another (pure geometry).
//!
//! Each point's label (its name, and under it the out-of-face component) sits at a fixed offset
//! right of the point. Labels are placed in order of importance (alarm, warning, watch, moving,
//! then stable points; by name within a rank). A label may meet neither a label already placed
//! nor another point's marker or arrow: where the whole label would, the name is tried alone (its
//! out-of-face line left to the tooltip), and where that would too, the label is hidden; the point
//! keeps its tooltip and its link. This is done twice, for the desktop
//! lettering (11 px names in plan units) and for the phone's (30 px names, as `dashboard.css`
//! draws them below 700 px), and the page hides each set with its own class.

use cliffwatch_core::analysis::AlertLevel;

/// What the decluttering needs of one point: its position in plan units (px of the SVG's
/// viewBox), the label's text and whether the out-of-face line is drawn under it.
#[derive(Debug, Clone)]
pub struct LabelInput<'a> {
    /// Point position, x (plan units, right).
    pub x: f64,
    /// Point position, y (plan units, down).
    pub y: f64,
    /// The name drawn.
    pub name: &'a str,
    /// The out-of-face text drawn under the name, if any.
    pub normal: Option<&'a str>,
    /// The point's alert level (labels of higher levels win).
    pub level: Option<AlertLevel>,
    /// A stable point (its label yields to those of monitored points).
    pub stable: bool,
    /// Where its displacement arrow ends, relative to the point (plan units, y down), if drawn.
    pub arrow: Option<(f64, f64)>,
}

/// How much of a point's label is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shown {
    /// The name and the out-of-face line.
    Full,
    /// The name only (the out-of-face line would meet something drawn).
    NameOnly,
    /// Nothing (the tooltip remains).
    Hidden,
}

/// Lettering of one layout: font sizes and offsets in plan units, as `dashboard.css` draws them.
#[derive(Debug, Clone, Copy)]
pub struct Lettering {
    /// Font size of the name.
    pub name_px: f64,
    /// Baseline of the name below the point (negative: above).
    pub name_baseline: f64,
    /// Font size of the out-of-face line.
    pub normal_px: f64,
    /// Baseline of the out-of-face line below the point.
    pub normal_baseline: f64,
    /// Left edge of the name right of the point.
    pub left: f64,
    /// Left edge of the out-of-face line right of the point.
    pub normal_left: f64,
    /// Half the size of a point's marker (circle or triangle) as drawn.
    pub marker_half: f64,
    /// Half the size of an arrow's head as drawn.
    pub arrow_head_half: f64,
}

/// The desktop lettering: 11 px names 7 above the point, 10 px out-of-face line 12 below.
pub const DESKTOP: Lettering = Lettering {
    name_px: 11.0,
    name_baseline: -7.0,
    normal_px: 10.0,
    normal_baseline: 12.0,
    left: 9.0,
    normal_left: 9.0,
    marker_half: 8.0,
    arrow_head_half: 5.0,
};

/// The phone lettering (below 700 px): 30 px names moved by (8, −4), 22 px lines by (10, 16);
/// markers drawn twice as large, arrows twice as thick.
pub const PHONE: Lettering = Lettering {
    name_px: 30.0,
    name_baseline: -11.0,
    normal_px: 22.0,
    normal_baseline: 28.0,
    left: 17.0,
    normal_left: 19.0,
    marker_half: 16.0,
    arrow_head_half: 10.0,
};

/// Width of a character as a share of the font size: a bound for system sans-serif digits,
/// capitals, "⊥" and "±" (Chromium drew "⊥ +15.3 mm" 0.66 font sizes a character wide).
const CHAR_WIDTH: f64 = 0.72;

/// A label's box: (left, top, right, bottom) in plan units; with its out-of-face line when
/// `with_normal` (and the point has one).
pub fn label_box(p: &LabelInput<'_>, l: &Lettering, with_normal: bool) -> [f64; 4] {
    let chars = |s: &str| s.chars().count() as f64;
    let mut right = p.x + l.left + CHAR_WIDTH * l.name_px * chars(p.name);
    let top = p.y + l.name_baseline - l.name_px;
    let mut bottom = p.y + l.name_baseline + 0.25 * l.name_px;
    let mut left = p.x + l.left;
    if let Some(n) = p.normal.filter(|_| with_normal) {
        right = right.max(p.x + l.normal_left + CHAR_WIDTH * l.normal_px * chars(n));
        bottom = p.y + l.normal_baseline + 0.25 * l.normal_px;
        left = left.min(p.x + l.normal_left);
    }
    [left, top, right, bottom]
}

/// The box a point's marker and arrow cover, in plan units.
pub fn marker_box(p: &LabelInput<'_>, l: &Lettering) -> [f64; 4] {
    let m = l.marker_half;
    let mut b = [p.x - m, p.y - m, p.x + m, p.y + m];
    if let Some((dx, dy)) = p.arrow {
        let (ex, ey, h) = (p.x + dx, p.y + dy, l.arrow_head_half);
        b = [
            b[0].min(ex - h),
            b[1].min(ey - h),
            b[2].max(ex + h),
            b[3].max(ey + h),
        ];
    }
    b
}

fn overlap(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

fn rank(p: &LabelInput<'_>) -> u8 {
    match p.level {
        Some(AlertLevel::Alarm) => 0,
        Some(AlertLevel::Warning) => 1,
        Some(AlertLevel::Watch) => 2,
        None if !p.stable => 3,
        None => 4,
    }
}

/// For each point, how much of its label is drawn with lettering `l`: no drawn label meets
/// another, nor another point's marker or arrow.
pub fn shown(points: &[LabelInput<'_>], l: &Lettering) -> Vec<Shown> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        (rank(&points[a]), points[a].name).cmp(&(rank(&points[b]), points[b].name))
    });
    let markers: Vec<[f64; 4]> = points.iter().map(|p| marker_box(p, l)).collect();
    let mut placed: Vec<[f64; 4]> = Vec::new();
    let mut out = vec![Shown::Hidden; points.len()];
    for i in order {
        let free = |b: &[f64; 4]| {
            placed.iter().all(|q| !overlap(q, b))
                && markers
                    .iter()
                    .enumerate()
                    .all(|(j, m)| j == i || !overlap(m, b))
        };
        let full = label_box(&points[i], l, true);
        let name = label_box(&points[i], l, false);
        if free(&full) {
            placed.push(full);
            out[i] = Shown::Full;
        } else if points[i].normal.is_some() && free(&name) {
            placed.push(name);
            out[i] = Shown::NameOnly;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crowded_labels_give_way_to_the_alarm_and_never_overlap() {
        let names: Vec<String> = (0..40).map(|i| format!("T{i:03}")).collect();
        // A grid as tight as each lettering's names allow: the out-of-face lines do not fit.
        let grid = |l: &Lettering| -> Vec<LabelInput<'_>> {
            names
                .iter()
                .enumerate()
                .map(|(i, n)| LabelInput {
                    x: 100.0 + (i % 8) as f64 * 5.0 * l.name_px,
                    y: 100.0 + (i / 8) as f64 * 3.0 * l.name_px,
                    name: n,
                    normal: (i % 2 == 0).then_some("⊥ +1.2 mm"),
                    level: (i == 17).then_some(AlertLevel::Alarm),
                    stable: i < 8,
                    arrow: (i % 3 == 0).then_some((4.0, 9.0)),
                })
                .collect()
        };
        for l in [DESKTOP, PHONE] {
            let pts = grid(&l);
            let drawn = shown(&pts, &l);
            assert!(drawn.iter().all(|k| *k != Shown::Hidden), "every name fits");
            assert_ne!(drawn[17], Shown::Hidden, "the alarm's name is drawn");
            assert!(drawn.iter().any(|k| *k != Shown::Full), "some give way");
            let boxes: Vec<(usize, [f64; 4])> = (0..pts.len())
                .filter(|&i| drawn[i] != Shown::Hidden)
                .map(|i| (i, label_box(&pts[i], &l, drawn[i] == Shown::Full)))
                .collect();
            for (a, (i, ba)) in boxes.iter().enumerate() {
                for (_, bb) in &boxes[a + 1..] {
                    assert!(!overlap(ba, bb), "{ba:?} / {bb:?}");
                }
                for (j, p) in pts.iter().enumerate() {
                    assert!(j == *i || !overlap(ba, &marker_box(p, &l)), "{ba:?} on {j}");
                }
            }
        }
        // Crowded: names give way, the alarm's first, never over another point's marker.
        let crowded: Vec<LabelInput<'_>> = grid(&DESKTOP)
            .into_iter()
            .enumerate()
            .map(|(i, p)| LabelInput {
                x: 100.0 + (i % 8) as f64 * 30.0,
                ..p
            })
            .collect();
        for l in [DESKTOP, PHONE] {
            let drawn = shown(&crowded, &l);
            assert!(drawn.contains(&Shown::Hidden), "some names give way");
            for (i, d) in drawn.iter().enumerate() {
                if *d != Shown::Hidden {
                    let b = label_box(&crowded[i], &l, *d == Shown::Full);
                    for (j, p) in crowded.iter().enumerate() {
                        assert!(j == i || !overlap(&b, &marker_box(p, &l)), "{i} over {j}");
                    }
                }
            }
        }
        // Two labels that meet: the alarm's is drawn whole, the other gives way; without the
        // alarm the first by name is drawn whole and the other keeps its name.
        let pair = |level: Option<AlertLevel>| {
            let a = LabelInput {
                x: 100.0,
                y: 100.0,
                name: "T9",
                normal: Some("⊥ +1.2 mm"),
                level,
                stable: false,
                arrow: None,
            };
            let b = LabelInput {
                y: 125.0,
                name: "T1",
                level: None,
                ..a.clone()
            };
            shown(&[a, b], &DESKTOP)
        };
        assert_eq!(pair(Some(AlertLevel::Alarm)), [Shown::Full, Shown::Hidden]);
        assert_eq!(pair(None), [Shown::NameOnly, Shown::Full]);
        // Far apart: every label drawn.
        let sparse: Vec<LabelInput<'_>> = grid(&DESKTOP)
            .into_iter()
            .enumerate()
            .map(|(i, p)| LabelInput {
                x: (i % 8) as f64 * 300.0,
                y: (i / 8) as f64 * 200.0,
                ..p
            })
            .collect();
        assert!(shown(&sparse, &PHONE).iter().all(|k| *k == Shown::Full));
    }
}
