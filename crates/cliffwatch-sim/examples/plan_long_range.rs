//! Campaign design on the long-range cliff (issue 78's worked example, `docs/campaign-design.md`):
//! the pre-analysis of `cliffwatch plan` ([`cliffwatch_core::plan::pre_analysis`]) for 3, 4 and 5
//! of the scene's camera stations and two lenses, printed as a markdown table of the block's
//! minimum detectable displacement.
//!
//! `cargo run --release -p cliffwatch-sim --example plan_long_range`
//!
//! The scene is [`cliffwatch_sim::scenes::long_range`] with its defaults (seed 1: 28 targets on a
//! 5 m × 3 m face with 1 m relief, 5 stations `S1…S5` evenly along a 60 m base 100–110 m away,
//! 10.5 µm pixels, 2160 × 1440 sensor). The targets' roles are those the monitoring series
//! ([`cliffwatch_sim::series::image_series`], default scenario, same seed and geometry) gives
//! them: the 5 targets nearest the face centre are the block, the 10 farthest the stable points
//! (the plan's known targets, σ 1 mm, control datum). Stations: 3 = S1, S3, S5; 4 = S1, S2, S4,
//! S5; 5 = S1–S5, each placed and aimed exactly as in the scene (up = the image's y axis). Lenses:
//! the scene's 400 mm and a 200 mm on the same sensor; c self-calibrated; image σ 0.25 px; face
//! normal +Z (the scene's frame: Z out of the face toward the cameras); confidence 0.95, power 0.8.

use cliffwatch_core::plan::{
    pre_analysis, Plan, PlanCamera, PlanReport, PlanStation, PlanTarget, TargetPrecision,
};
use cliffwatch_sim::scenes::{long_range, LongRangeParams, Truth};
use cliffwatch_sim::series::{image_series, ImageSeriesScenario};

/// σ of one image coordinate, pixels (the scene's image noise).
const SIGMA_PX: f64 = 0.25;

/// The principal distances compared, mm: the scene's lens and one of half its focal length.
const LENSES_MM: [f64; 2] = [400.0, 200.0];

/// The station sets compared: the two ends and the middle, then the four off-centre stations,
/// then all five.
const STATION_SETS: [&[&str]; 3] = [
    &["S1", "S3", "S5"],
    &["S1", "S2", "S4", "S5"],
    &["S1", "S2", "S3", "S4", "S5"],
];

/// A target's role in the example: (name, known stable point, on the block).
type Role = (String, bool, bool);

/// The targets' roles as the monitoring series marks them, checked to lie where the scene puts
/// them (same seed, same geometry).
fn roles(truth: &Truth) -> Vec<Role> {
    let series = image_series(&ImageSeriesScenario {
        epochs: 1,
        ..ImageSeriesScenario::default()
    })
    .expect("the monitoring series");
    series
        .truth
        .points
        .iter()
        .map(|p| {
            let xyz = truth.points.get(&p.name).expect("a target of the scene");
            let far = (0..3)
                .map(|i| (xyz[i] - p.xyz_m[i]).abs())
                .fold(0.0, f64::max);
            assert!(far < 1e-9, "{}: the series and the scene disagree", p.name);
            (p.name.clone(), p.role == "stable", p.group.is_some())
        })
        .collect()
}

/// The plan of the scene with the given stations and principal distance.
fn plan(p: &LongRangeParams, truth: &Truth, roles: &[Role], stations: &[&str], c_mm: f64) -> Plan {
    let centre = [0.0, p.face_height_m / 2.0, p.relief_m / 2.0];
    let stations = stations
        .iter()
        .map(|name| {
            let cam = &truth.cameras[*name];
            let r3 = cam.r[2];
            let d = (0..3)
                .map(|i| (cam.xo[i] - centre[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            PlanStation {
                name: name.to_string(),
                camera: "cam".into(),
                position: cam.xo,
                // The camera looks along −r3: aimed at the point at the face's distance.
                aim: std::array::from_fn(|i| cam.xo[i] - d * r3[i]),
                up: Some(cam.r[1]),
                sees: None,
            }
        })
        .collect();
    let targets = roles
        .iter()
        .map(|(name, known, _)| PlanTarget {
            point: name.clone(),
            xyz: truth.points[name],
            known: *known,
            sigma_m: None,
        })
        .collect();
    Plan {
        model: Default::default(),
        sigma_px: SIGMA_PX,
        confidence: 0.95,
        power: 0.8,
        known_sigma_m: 0.001,
        datum: Default::default(),
        face_normal: Some([0.0, 0.0, 1.0]),
        cameras: vec![PlanCamera {
            id: "cam".into(),
            c_mm,
            calibrate_c: true,
            pixel_size_mm: p.pixel_size_mm,
            width_px: p.width_px,
            height_px: p.height_px,
            sigma_px: None,
        }],
        stations,
        targets,
    }
}

/// The median and the largest of some values (None for none).
fn median_max(mut v: Vec<f64>) -> Option<(f64, f64)> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = match n {
        0 => return None,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    };
    Some((median, v[n - 1]))
}

/// "median / worst" of one figure over the block's targets, mm ("—" where a target is not
/// measured).
fn block_figure(block: &[&TargetPrecision], f: impl Fn(&TargetPrecision) -> Option<f64>) -> String {
    let v: Option<Vec<f64>> = block.iter().map(|t| f(t)).collect();
    match v.and_then(median_max) {
        Some((m, w)) => format!("{m:.1} / {w:.1}"),
        None => "—".into(),
    }
}

/// One row of the table and the report's warnings.
fn row(stations: &[&str], c_mm: f64, report: &PlanReport, roles: &[Role]) -> String {
    let block: Vec<&TargetPrecision> = report
        .targets
        .iter()
        .filter(|t| roles.iter().any(|(n, _, b)| *b && *n == t.point))
        .collect();
    let unseen = report.targets.iter().filter(|t| t.cameras < 2).count();
    format!(
        "| {} ({}) | {c_mm:.0} mm | {} | {} | {} | {} | {} |",
        stations.len(),
        stations.join(", "),
        block_figure(&block, |t| t.mdd_normal_mm),
        block_figure(&block, |t| t.mdd_3d_mm),
        report.sigma_c_mm.map_or("fixed".into(), |s| format!(
            "{s:.1} mm ({:.1} %)",
            100.0 * s / c_mm
        )),
        unseen,
        report.warnings.len(),
    )
}

/// Builds the six plans, runs the pre-analysis on each and prints the table and the warnings.
fn main() {
    let p = LongRangeParams::default();
    let (_, truth) = long_range(&p).expect("the long-range scene");
    let roles = roles(&truth);
    let block: Vec<&str> = roles.iter().filter(|r| r.2).map(|r| r.0.as_str()).collect();
    let stable = roles.iter().filter(|r| r.1).count();
    println!(
        "Long-range cliff, seed {}: {} targets, block {} ({} targets), {stable} stable (known, σ \
         1 mm); image σ {SIGMA_PX} px; confidence 0.95, power 0.8.\n",
        p.seed,
        roles.len(),
        block.join(", "),
        block.len()
    );
    println!(
        "| cameras | lens c | block MDD along the normal, mm (median / worst) | block MDD 3-D \
         worst direction, mm (median / worst) | σ of c | targets seen by < 2 | warnings |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut notes = Vec::new();
    for c_mm in LENSES_MM {
        for stations in STATION_SETS {
            let plan = plan(&p, &truth, &roles, stations, c_mm);
            match pre_analysis(&plan) {
                Ok(report) => {
                    println!("{}", row(stations, c_mm, &report, &roles));
                    for w in &report.warnings {
                        notes.push(format!("- {} cameras, {c_mm:.0} mm: {w}", stations.len()));
                    }
                }
                Err(e) => println!(
                    "| {} ({}) | {c_mm:.0} mm | — | — | — | — | plan fails: {e} |",
                    stations.len(),
                    stations.join(", ")
                ),
            }
        }
    }
    if !notes.is_empty() {
        println!("\nWarnings:\n{}", notes.join("\n"));
    }
}
