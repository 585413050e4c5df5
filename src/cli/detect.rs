//! `cliffwatch detect IMAGE... [--polarity auto|bright|dark] [--min-diameter-px D]
//! [--max-diameter-px D] [--overlay DIR]`: detects and centres the targets of each image and prints
//! one JSON object per image per line (JSON Lines), in the order given. Pixel coordinates: the
//! centre of the top-left pixel is (0, 0), as in the upload form. A file that cannot be read or
//! decoded is named on standard error and the rest go on; the exit status is then 1.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use cliffwatch_core::detect::{
    decode, detect, DetectOptions, Detections, GreyImage, Polarity, MAX_IMAGE_FILE_BYTES,
};
use rayon::prelude::*;
use serde_json::json;

use super::overlay;

/// Which targets `--polarity` looks for.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum PolarityArg {
    /// Both searched, the one that yields more targets kept.
    Auto,
    /// Bright targets on a darker background.
    Bright,
    /// Dark targets on a brighter background.
    Dark,
}

/// Arguments of `cliffwatch detect`.
#[derive(clap::Args)]
pub struct DetectArgs {
    /// Images (JPEG, PNG or TIFF).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Target polarity.
    #[arg(long, value_enum, default_value = "auto")]
    pub polarity: PolarityArg,
    /// Smallest target diameter in px.
    #[arg(long)]
    pub min_diameter_px: Option<f64>,
    /// Largest target diameter in px.
    #[arg(long)]
    pub max_diameter_px: Option<f64>,
    /// Directory to write each image into with its targets circled and numbered
    /// (`NAME.targets.jpg`; the number is the target's index in the JSON line).
    #[arg(long)]
    pub overlay: Option<PathBuf>,
}

/// The options `args` ask for.
pub fn options(args: &DetectArgs) -> DetectOptions {
    let mut o = DetectOptions {
        polarity: match args.polarity {
            PolarityArg::Auto => None,
            PolarityArg::Bright => Some(Polarity::BrightOnDark),
            PolarityArg::Dark => Some(Polarity::DarkOnBright),
        },
        ..DetectOptions::default()
    };
    if let Some(d) = args.min_diameter_px {
        o.min_diameter_px = d;
    }
    if let Some(d) = args.max_diameter_px {
        o.max_diameter_px = d;
    }
    o
}

/// Reads and decodes one file; the error names nothing (the caller adds the path).
fn read(path: &Path) -> anyhow::Result<GreyImage> {
    let len = std::fs::metadata(path)?.len();
    if len > MAX_IMAGE_FILE_BYTES {
        anyhow::bail!("file of {len} bytes exceeds the limit of {MAX_IMAGE_FILE_BYTES} bytes");
    }
    let bytes = std::fs::read(path)?;
    Ok(decode(&bytes)?)
}

/// Detects in one file: the JSON line, or the error.
fn one(path: &Path, opts: &DetectOptions, overlay_dir: Option<&Path>) -> anyhow::Result<String> {
    let t0 = Instant::now();
    let img = read(path)?;
    let d = detect(&img, opts)?;
    let elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    if let Some(dir) = overlay_dir {
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "image".into());
        let out = dir.join(format!("{name}.targets.jpg"));
        overlay::write(&img, &d.targets, &out)
            .with_context(|| format!("writing the overlay {}", out.display()))?;
    }
    Ok(line(path, &d, elapsed_ms).to_string())
}

/// The JSON object of one image.
pub fn line(path: &Path, d: &Detections, elapsed_ms: f64) -> serde_json::Value {
    let targets: Vec<_> = d
        .targets
        .iter()
        .map(|t| {
            json!({
                "col": t.col,
                "row": t.row,
                "diameter_px": t.diameter_px,
                "sigma_col_px": t.sigma_col_px,
                "sigma_row_px": t.sigma_row_px,
                "contrast": t.contrast,
                "quality": t.snr,
                "method": t.method.name(),
            })
        })
        .collect();
    json!({
        "image": path.display().to_string(),
        "width_px": d.width,
        "height_px": d.height,
        "polarity": d.polarity.name(),
        "noise": d.noise,
        "elapsed_ms": elapsed_ms,
        "candidates": d.candidates,
        "warnings": d.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        "targets": targets,
    })
}

/// Runs `cliffwatch detect`.
pub fn run(args: DetectArgs) -> anyhow::Result<()> {
    let opts = options(&args);
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the overlay directory {}", dir.display()))?;
    }
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut failed = 0usize;
    // a few images at a time, in parallel, printed in the order given
    let batch = 2 * rayon::current_num_threads().max(1);
    for chunk in args.images.chunks(batch) {
        let results: Vec<_> = chunk
            .par_iter()
            .map(|p| one(p, &opts, args.overlay.as_deref()))
            .collect();
        for (path, r) in chunk.iter().zip(results) {
            match r {
                Ok(l) => writeln!(out, "{l}")?,
                Err(e) => {
                    failed += 1;
                    out.flush()?;
                    eprintln!("cliffwatch detect: {}: {e:#}", path.display());
                }
            }
        }
        out.flush()?;
    }
    if failed > 0 {
        anyhow::bail!(
            "{failed} of {} images could not be measured",
            args.images.len()
        );
    }
    Ok(())
}
