//! Real photographs: DBAT's 21 images of a calibration field of black printed dots
//! (`../shared/data/real/dbat-camcal`), detected with `DetectOptions::default()` (no tuning) and
//! compared with PhotoModeler's 2074 marks of the same images. The images are read at test time.

use std::sync::OnceLock;

use cliffwatch_core::detect::{detect_bytes, CentreMethod, DetectOptions, Detections, Polarity};

pub use crate::support::dbat::{marks, DIR};

/// Every image's detections with the default options, computed once for all tests.
pub fn detections() -> &'static Vec<(String, Detections)> {
    static D: OnceLock<Vec<(String, Detections)>> = OnceLock::new();
    D.get_or_init(|| {
        let mut names: Vec<String> = marks().into_keys().collect();
        names.sort();
        names
            .into_iter()
            .map(|n| {
                let bytes = std::fs::read(format!("{DIR}/images/{n}")).expect("image");
                let d = detect_bytes(&bytes, &DetectOptions::default()).expect("detects");
                (n, d)
            })
            .collect()
    })
}

/// One mark with the detection within 3 px of it.
pub struct Match {
    /// Mark column and row (px).
    pub mark: [f64; 2],
    /// Detection − mark (col, row; px).
    pub offset: [f64; 2],
    /// How the detection was centred.
    pub method: CentreMethod,
}

/// The comparison with PhotoModeler: the matched marks; the count of detections 3 px from every
/// mark.
pub struct Comparison {
    /// Marks with a detection.
    pub matched: Vec<Match>,
    /// Marks without a detection: (image, point id, col, row).
    pub missed: Vec<(String, u32, f64, f64)>,
    /// Detections far from every mark.
    pub extra: usize,
    /// Marks in all.
    pub marks: usize,
}

pub fn compare() -> Comparison {
    let marks = marks();
    let mut c = Comparison {
        matched: Vec::new(),
        missed: Vec::new(),
        extra: 0,
        marks: 0,
    };
    for (name, d) in detections() {
        let mk = &marks[name];
        c.marks += mk.len();
        for &(id, mc, mr) in mk {
            let best = d
                .targets
                .iter()
                .map(|t| ((t.col - mc).hypot(t.row - mr), t))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match best {
                Some((e, t)) if e < 3.0 => c.matched.push(Match {
                    mark: [mc, mr],
                    offset: [t.col - mc, t.row - mr],
                    method: t.method,
                }),
                _ => c.missed.push((name.clone(), id, mc, mr)),
            }
        }
        c.extra += d
            .targets
            .iter()
            .filter(|t| {
                mk.iter()
                    .all(|&(_, mc, mr)| (t.col - mc).hypot(t.row - mr) >= 3.0)
            })
            .count();
    }
    c
}

/// rms distance to the marks after removing the mean offset, and the offset.
fn rms_after_offset(c: &Comparison) -> (f64, [f64; 2]) {
    let n = c.matched.len() as f64;
    let mx = c.matched.iter().map(|m| m.offset[0]).sum::<f64>() / n;
    let my = c.matched.iter().map(|m| m.offset[1]).sum::<f64>() / n;
    let ss: f64 = c
        .matched
        .iter()
        .map(|m| (m.offset[0] - mx).powi(2) + (m.offset[1] - my).powi(2))
        .sum();
    ((ss / n).sqrt(), [mx, my])
}

#[test]
fn real_default_options_find_the_dark_targets() {
    let c = compare();
    let found = c.matched.len();
    eprintln!(
        "dbat-camcal, default options: {found}/{} marks found, {} extra; missed {:?}",
        c.marks, c.extra, c.missed
    );
    for (name, d) in detections() {
        assert_eq!(
            d.polarity,
            Polarity::DarkOnBright,
            "{name}: dark targets not recognised"
        );
        assert!(d.warnings.is_empty(), "{name}: {:?}", d.warnings);
    }
    assert_eq!(c.marks, 2074);
    // bound: at least 99.5 % of PhotoModeler's marks (measured 2072)
    assert!(found as f64 >= 0.995 * c.marks as f64, "{found} found");
    // bound: extras (unmarked dots of the field, code segments, lettering, wood grain) ≤ 70 per
    // image (measured 1280 in all)
    assert!(c.extra <= 21 * 70, "{} extra detections", c.extra);
}

#[test]
fn real_targets_near_the_border_are_measured() {
    let c = compare();
    let (w, h) = (2272.0, 1704.0);
    let near = |col: f64, row: f64| row < 65.0 || row > h - 66.0 || col < 65.0 || col > w - 66.0;
    let found = c
        .matched
        .iter()
        .filter(|m| near(m.mark[0], m.mark[1]))
        .count();
    let missed: Vec<_> = c.missed.iter().filter(|m| near(m.2, m.3)).collect();
    eprintln!("marks within 65 px of the border: {found} found, missed {missed:?}");
    // 32 of PhotoModeler's marks lie within 65 px of the border
    assert!(found >= 30, "{found} border marks found");
    assert!(missed.len() <= 2, "missed near the border: {missed:?}");
}

#[test]
fn real_centres_agree_with_photomodeler() {
    let c = compare();
    let (rms, off) = rms_after_offset(&c);
    let dual = c
        .matched
        .iter()
        .filter(|m| m.method == CentreMethod::DualConic)
        .count();
    eprintln!(
        "dbat-camcal: rms distance to PhotoModeler {rms:.4} px after offset ({:+.3}, {:+.3}) px over {} marks ({dual} by dual conic)",
        off[0],
        off[1],
        c.matched.len()
    );
    // the bound; OpenCV's findContours + fitEllipse: 0.172 px (benches/peers)
    assert!(rms <= 0.17, "rms {rms}");
    assert!(off[0].abs() < 0.1 && off[1].abs() < 0.1, "offset {off:?}");
}
