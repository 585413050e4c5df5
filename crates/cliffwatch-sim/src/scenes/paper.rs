//! Ono & Hattori's Table 1 scene (paper §4), cases 1–3.

use std::collections::BTreeMap;

use super::builder::*;
use cliffwatch_core::photogrammetry::input::epoch::EpochInput;

/// Which of the paper's simulation cases (Table 1, §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PaperCase {
    /// Images A, B; c = 300 mm fixed.
    Case1,
    /// Images A, B, C; c = 300 mm fixed.
    #[default]
    Case2,
    /// Images A, B, C; c given as 290 mm and self-calibrated.
    Case3,
}

/// Parameters of [`paper_table1`].
#[derive(Debug, Clone, PartialEq)]
pub struct PaperParams {
    /// The case (images and c).
    pub case: PaperCase,
    /// Seed of the noise and start-error draws.
    pub seed: u64,
    /// σ of the image noise per coordinate in mm (paper: 0.001).
    pub noise_mm: f64,
    /// σ of the start errors of the approximate coordinates per coordinate in m (paper: 0.010).
    pub approx_sigma_m: f64,
    /// A-priori σ written into the camera (`sigma_mm`); None leaves the form's default (0.002 mm),
    /// as in the shared epochs.
    pub sigma_mm: Option<f64>,
}

impl Default for PaperParams {
    fn default() -> Self {
        PaperParams {
            case: PaperCase::Case2,
            seed: 101,
            noise_mm: 0.001,
            approx_sigma_m: 0.010,
            sigma_mm: None,
        }
    }
}

impl PaperParams {
    /// Default parameters for one case and seed.
    pub fn case(case: PaperCase, seed: u64) -> Self {
        PaperParams {
            case,
            seed,
            ..PaperParams::default()
        }
    }
}

/// True principal distance of the paper's scene in mm.
pub const PAPER_C_MM: f64 = 300.0;

/// The 12 points of the paper's Table 1 in m (X, Y, Z; Z toward the cameras).
pub const PAPER_POINTS: [[f64; 3]; 12] = [
    [-0.2, 0.8, 0.0],
    [-0.2, 0.5, 0.0],
    [-0.3, 0.1, 0.0],
    [-0.1, 0.7, 0.2],
    [-0.15, 0.35, 0.3],
    [0.1, 0.7, 0.0],
    [0.05, 0.45, 0.0],
    [0.25, 0.8, 0.35],
    [0.3, 0.55, 0.0],
    [0.25, 0.25, 0.25],
    [0.4, 0.8, 0.0],
    [0.4, 0.15, 0.0],
];

/// The paper's stations A, B, C in m; each looks at the centroid of the points with +Y up.
pub const PAPER_STATIONS: [(&str, [f64; 3]); 3] = [
    ("A", [-3.0, 0.5, 10.0]),
    ("B", [3.0, 0.4, 10.0]),
    ("C", [0.0, 0.4, 11.0]),
];

/// The paper's Table 1 scene (m): points 1–12, stations A, B (and C), c = 300 mm, image noise and
/// start errors per [`PaperParams`]. Observations in mm; every point gets an approximation.
pub fn paper_table1(params: &PaperParams) -> Result<(EpochInput, Truth), SceneError> {
    non_negative("noise_mm", params.noise_mm)?;
    non_negative("approx_sigma_m", params.approx_sigma_m)?;
    if let Some(s) = params.sigma_mm {
        positive("sigma_mm", s)?;
    }
    let names: Vec<String> = (1..=12).map(|i| i.to_string()).collect();
    let points: Vec<V3> = PAPER_POINTS.to_vec();
    let n = points.len() as f64;
    let centroid = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / n);
    let stations: &[(&str, V3)] = match params.case {
        PaperCase::Case1 => &PAPER_STATIONS[..2],
        _ => &PAPER_STATIONS[..],
    };
    let (c_given, calibrate) = match params.case {
        PaperCase::Case3 => (290.0, true),
        _ => (PAPER_C_MM, false),
    };
    let interior = [PAPER_C_MM, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut noise = stream(params.seed, NOISE);
    let mut truth = Truth {
        points: names.iter().cloned().zip(points.iter().copied()).collect(),
        cameras: BTreeMap::new(),
        c_mm: PAPER_C_MM,
        interior: None,
    };
    let mut images = Vec::new();
    for (id, xo) in stations {
        let r = look_at(*xo, centroid, [0.0, 1.0, 0.0]);
        let mut observations = Vec::new();
        for (name, p) in names.iter().zip(&points) {
            let xy = project(&r, *xo, &interior, *p)
                .ok_or_else(|| bad("case", "a point behind a camera"))?;
            let e = [gauss(&mut noise), gauss(&mut noise)];
            observations.push(mm_observation(
                name,
                [
                    xy[0] + params.noise_mm * e[0],
                    xy[1] + params.noise_mm * e[1],
                ],
            ));
        }
        add_image(
            &mut truth,
            &mut images,
            id,
            TruthCamera { xo: *xo, r },
            observations,
        );
    }
    let mut start = stream(params.seed, START);
    let approx = approx_list(
        &names,
        &points,
        &vec![false; names.len()],
        params.approx_sigma_m,
        &mut start,
    );
    let input = EpochInput {
        observed_at: timestamp(2000, params.seed),
        label: Some(format!(
            "paper Table 1 {:?} seed {}",
            params.case, params.seed
        )),
        cameras: vec![plain_camera("cam", c_given, calibrate, params.sigma_mm)],
        images,
        control: Vec::new(),
        approx,
    };
    Ok((input, truth))
}
