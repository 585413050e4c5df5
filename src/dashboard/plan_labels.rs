//! Which names of the face plan to draw so that none overlaps another (pure geometry).
//!
//! Each point's label (its name, and under it the out-of-face component) sits at a fixed offset
//! right of the point. Labels are placed in order of importance (alarm, warning, watch, moving,
//! then stable points; by name within a rank); a label whose box meets one already placed is
//! hidden, and the point keeps its tooltip and its link. This is done twice, for the desktop
//! lettering (11 px names in plan units) and for the phone's (30 px names, as `dashboard.css`
//! draws them below 700 px), and the page hides each set with its own class.

use crate::analysis::AlertLevel;

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
}

/// The desktop lettering: 11 px names 7 above the point, 10 px out-of-face line 12 below.
pub const DESKTOP: Lettering = Lettering {
    name_px: 11.0,
    name_baseline: -7.0,
    normal_px: 10.0,
    normal_baseline: 12.0,
    left: 9.0,
    normal_left: 9.0,
};

/// The phone lettering (below 700 px): 30 px names moved by (8, −4), 22 px lines by (10, 16).
pub const PHONE: Lettering = Lettering {
    name_px: 30.0,
    name_baseline: -11.0,
    normal_px: 22.0,
    normal_baseline: 28.0,
    left: 17.0,
    normal_left: 19.0,
};

/// Width of a character as a share of the font size: a bound for system sans-serif digits,
/// capitals, "⊥" and "±" (Chromium drew "⊥ +15.3 mm" 0.66 font sizes a character wide).
const CHAR_WIDTH: f64 = 0.72;

/// A label's box: (left, top, right, bottom) in plan units.
pub fn label_box(p: &LabelInput<'_>, l: &Lettering) -> [f64; 4] {
    let chars = |s: &str| s.chars().count() as f64;
    let mut right = p.x + l.left + CHAR_WIDTH * l.name_px * chars(p.name);
    let top = p.y + l.name_baseline - l.name_px;
    let mut bottom = p.y + l.name_baseline + 0.25 * l.name_px;
    if let Some(n) = p.normal {
        right = right.max(p.x + l.normal_left + CHAR_WIDTH * l.normal_px * chars(n));
        bottom = p.y + l.normal_baseline + 0.25 * l.normal_px;
    }
    [p.x + l.left.min(l.normal_left), top, right, bottom]
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

/// For each point, whether its label is drawn with lettering `l` (none overlaps another drawn).
pub fn shown(points: &[LabelInput<'_>], l: &Lettering) -> Vec<bool> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        (rank(&points[a]), points[a].name).cmp(&(rank(&points[b]), points[b].name))
    });
    let mut placed: Vec<[f64; 4]> = Vec::new();
    let mut keep = vec![false; points.len()];
    for i in order {
        let b = label_box(&points[i], l);
        if placed.iter().all(|q| !overlap(q, &b)) {
            placed.push(b);
            keep[i] = true;
        }
    }
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crowded_labels_give_way_to_the_alarm_and_never_overlap() {
        let names: Vec<String> = (0..40).map(|i| format!("T{i:03}")).collect();
        let pts: Vec<LabelInput<'_>> = names
            .iter()
            .enumerate()
            .map(|(i, n)| LabelInput {
                x: 100.0 + (i % 8) as f64 * 20.0,
                y: 100.0 + (i / 8) as f64 * 12.0,
                name: n,
                normal: (i % 2 == 0).then_some("⊥ +1.2 mm"),
                level: (i == 17).then_some(AlertLevel::Alarm),
                stable: i < 8,
            })
            .collect();
        for l in [DESKTOP, PHONE] {
            let keep = shown(&pts, &l);
            assert!(keep[17], "the alarm's label is drawn");
            assert!(keep.iter().filter(|k| !**k).count() > 0, "some give way");
            let boxes: Vec<[f64; 4]> = (0..pts.len())
                .filter(|&i| keep[i])
                .map(|i| label_box(&pts[i], &l))
                .collect();
            for (a, ba) in boxes.iter().enumerate() {
                for bb in &boxes[a + 1..] {
                    assert!(!overlap(ba, bb), "{ba:?} / {bb:?}");
                }
            }
        }
        // Far apart: every label drawn.
        let sparse: Vec<LabelInput<'_>> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| LabelInput {
                x: (i % 8) as f64 * 300.0,
                y: (i / 8) as f64 * 200.0,
                ..p.clone()
            })
            .collect();
        assert!(shown(&sparse, &PHONE).iter().all(|k| *k));
    }
}
