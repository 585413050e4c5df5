//! DBAT's 21 real photographs of a calibration field (`../shared/data/real/dbat-camcal`, read at
//! test time) and PhotoModeler's measurement of them: its marks and its 3-D points.

use std::collections::HashMap;

/// The data's directory.
pub const DIR: &str = concat!(shared_dir!(), "/data/real/dbat-camcal");

/// Image width and height in px.
pub const SIZE_PX: (u32, u32) = (2272, 1704);

/// PhotoModeler's format width in mm over the width in px.
pub const PIXEL_MM: f64 = 7.25319 / 2272.0;

/// PhotoModeler's principal distance in mm (the start of the self-calibration).
pub const C_MM: f64 = 7.4653;

/// The four coded targets at the corners of a 1 m square, PhotoModeler's datum.
pub const CODED: [u32; 4] = [1001, 1002, 1003, 1004];

/// PhotoModeler's export.
fn export() -> String {
    std::fs::read_to_string(format!("{DIR}/camcal-pmexport.txt")).expect("pmexport")
}

/// PhotoModeler's marks per image file name: (point id, col, row) with cliffwatch's pixel
/// convention (PhotoModeler puts the centre of the top-left pixel at (0.5, 0.5)).
pub fn marks() -> HashMap<String, Vec<(u32, f64, f64)>> {
    let text = export();
    let mut names = HashMap::new();
    let mut by_index: HashMap<u32, Vec<(u32, f64, f64)>> = HashMap::new();
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if t.len() == 2 && t[1].to_ascii_lowercase().ends_with(".jpg") {
            let name = t[1].rsplit('/').next().unwrap().to_string();
            names.insert(t[0].parse::<u32>().unwrap(), name);
        } else if t.len() == 6 && t[4] == "0.10000" {
            let f = |i: usize| t[i].parse::<f64>().unwrap();
            by_index.entry(t[0].parse().unwrap()).or_default().push((
                t[1].parse().unwrap(),
                f(2) - 0.5,
                f(3) - 0.5,
            ));
        }
    }
    by_index
        .into_iter()
        .map(|(i, m)| (names[&i].clone(), m))
        .collect()
}

/// PhotoModeler's 3-D points (id, X, Y, Z in m) from the export: the lines of 7 fields after the
/// last image's block (its position and their σ: the first two 7-field lines after its name).
pub fn pm_points() -> Vec<(u32, [f64; 3])> {
    let text = export();
    let lines: Vec<&str> = text.lines().collect();
    let last = lines
        .iter()
        .rposition(|l| l.to_ascii_lowercase().ends_with(".jpg"))
        .expect("image lines");
    lines[last + 1..]
        .iter()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|t| t.len() == 7)
        .skip(2)
        .map(|t| {
            let f = |i: usize| t[i].parse::<f64>().unwrap();
            (t[0].parse().unwrap(), [f(1), f(2), f(3)])
        })
        .collect()
}
