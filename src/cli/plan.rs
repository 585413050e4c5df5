//! `cliffwatch plan PLAN.json`: campaign design. Prints the pre-analysis of a planned camera
//! network (JSON, indented when standard output is a terminal): per target the predicted σ, the σ
//! along the face normal and the minimum detectable displacement between two epochs, and the
//! network's figures (σ of c, confidence, power, warnings in words).
//!
//! The plan (JSON; every length in m in the site frame unless it says mm or px):
//! ```json
//! {
//!   "sigma_px": 0.25,             // σ of one image coordinate, pixels
//!   "confidence": 0.95,           // optional (default 0.95): the displacement test's confidence
//!   "power": 0.8,                 // optional (default 0.8): detection probability of the MDD
//!   "known_sigma_m": 0.001,       // optional (default 0.001): σ of a known point's coordinates
//!   "face_normal": [0, 1, 0],     // optional: default from the targets toward the stations
//!   "model": "orthogonal",        // optional: orthogonal (default) or central
//!   "cameras": [{"id": "cam", "c_mm": 400, "pixel_size_mm": 0.0105,
//!                "width_px": 2160, "height_px": 1440,
//!                "calibrate_c": true, "sigma_px": 0.25}],   // the last two optional
//!   "stations": [{"name": "S1", "camera": "cam", "position": [-30, 150, 0],
//!                 "aim": [0, 0, 1.5], "up": [0, 0, 1]}],     // up optional (default Z up)
//!   "targets": [{"point": "T1", "xyz": [-2, 0.3, 0.5], "known": true, "sigma_m": 0.001}]
//! }
//! ```
//! (comments for reading only: the file is plain JSON.) A target is seen by a station when it
//! lies in front of it and inside its sensor. The method, and the exact output, are those of
//! [`cliffwatch_core::plan::pre_analysis`] and [`cliffwatch_core::plan::PlanReport`]
//! (`docs/api.md`, "Campaign design").

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use anyhow::Context;
use cliffwatch_core::plan::{pre_analysis, Plan};

/// Arguments of `cliffwatch plan`.
#[derive(clap::Args)]
pub struct PlanArgs {
    /// The planned network (JSON, see `docs/api.md`, "Campaign design").
    pub plan: PathBuf,
}

/// Runs `cliffwatch plan`.
pub fn run(args: PlanArgs) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(&args.plan)
        .with_context(|| format!("reading {}", args.plan.display()))?;
    let plan: Plan =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", args.plan.display()))?;
    let report = pre_analysis(&plan).context("analysing the plan")?;
    let stdout = std::io::stdout();
    let terminal = stdout.is_terminal();
    let mut out = std::io::BufWriter::new(stdout.lock());
    if terminal {
        serde_json::to_writer_pretty(&mut out, &report)?;
    } else {
        serde_json::to_writer(&mut out, &report)?;
    }
    writeln!(out)?;
    out.flush()?;
    Ok(())
}
