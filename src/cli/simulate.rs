//! `cliffwatch simulate --scene NAME --seed N [--out-dir DIR] [--blunder] [--epochs N]`: writes
//! `NAME-seedN.epoch.json` (upload form) and `NAME-seedN.truth.json` (the form of
//! [`cliffwatch_sim::scenes::Truth`]). The `monitoring-series` scene writes one upload per epoch,
//! `monitoring-series-seedN-KKK.epoch.json` (K from 1), and the series truth
//! `monitoring-series-seedN.truth.json` ([`cliffwatch_sim::series::SeriesTruth`]).

use std::path::PathBuf;

use anyhow::Context;
use cliffwatch_sim::scenes::{
    calibration, large, long_range, paper_table1, CalibrationParams, LabelSwap, LargeParams,
    LongRangeParams, PaperCase, PaperParams,
};
use cliffwatch_sim::series::{image_series, ImageSeriesScenario};

/// The scenes `cliffwatch simulate` can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SceneName {
    /// Paper Table 1, case 1: images A, B; c = 300 mm fixed.
    PaperCase1,
    /// Paper Table 1, case 2: images A, B, C; c = 300 mm fixed.
    PaperCase2,
    /// Paper Table 1, case 3: images A, B, C; c given as 290 mm, self-calibrated.
    PaperCase3,
    /// Long-range cliff: X along the face, Y up, Z toward the cameras (a site for it declares
    /// `"frame": {"up": [0, 1, 0]}`).
    LongRange,
    /// Long-range cliff in East-North-Up with UTM-sized coordinates.
    LongRangeEnu,
    /// Nearly flat face (5 cm relief over 5 m), Y up as `long-range`.
    Flat,
    /// Wide-angle calibration network (central model, full self-calibration); the plate in X-Y,
    /// Z up toward the cameras.
    Calibration,
    /// Benchmark network: 20 images × 500 points, each in 10 images.
    Large,
    /// Benchmark network: 100 images × 10 000 points, each in 10 images.
    Huge,
    /// A monitoring series of the long-range cliff (`--epochs` uploads, 12 h apart): stable targets
    /// around a block creeping then accelerating to failure, cameras re-set-up every epoch; Y up as
    /// `long-range`.
    MonitoringSeries,
}

/// Arguments of `cliffwatch simulate`.
#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Which scene.
    #[arg(long, value_enum)]
    pub scene: SceneName,
    /// Seed of the random draws (geometry, noise, start errors).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory to write into (created if missing): the upload and the truth, or for
    /// `monitoring-series` one upload per epoch and the series truth.
    #[arg(long, default_value = ".")]
    pub out_dir: PathBuf,
    /// Swap two targets' labels in one image (long-range scenes only).
    #[arg(long)]
    pub blunder: bool,
    /// Number of epochs of `monitoring-series` (failure 12 h after the 40th epoch).
    #[arg(long, default_value_t = 40)]
    pub epochs: usize,
}

fn write(path: std::path::PathBuf, text: String) -> anyhow::Result<()> {
    std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
    println!("{}", path.display());
    Ok(())
}

fn monitoring_series(args: &SimulateArgs) -> anyhow::Result<()> {
    let series = image_series(&ImageSeriesScenario {
        seed: args.seed,
        epochs: args.epochs,
        ..ImageSeriesScenario::default()
    })
    .context("generating the monitoring series")?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    let stem = format!("monitoring-series-seed{}", args.seed);
    for (k, epoch) in series.epochs.iter().enumerate() {
        write(
            args.out_dir.join(format!("{stem}-{:03}.epoch.json", k + 1)),
            serde_json::to_string_pretty(epoch)?,
        )?;
    }
    write(
        args.out_dir.join(format!("{stem}.truth.json")),
        serde_json::to_string_pretty(&series.truth)?,
    )
}

/// Runs `cliffwatch simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let seed = args.seed;
    let swap = args.blunder.then(LabelSwap::default);
    if args.blunder
        && !matches!(
            args.scene,
            SceneName::LongRange | SceneName::LongRangeEnu | SceneName::Flat
        )
    {
        anyhow::bail!("--blunder applies to long-range, long-range-enu and flat only");
    }
    let paper = |case| paper_table1(&PaperParams::case(case, seed));
    let (name, generated) = match args.scene {
        SceneName::PaperCase1 => ("paper-case1", paper(PaperCase::Case1)),
        SceneName::PaperCase2 => ("paper-case2", paper(PaperCase::Case2)),
        SceneName::PaperCase3 => ("paper-case3", paper(PaperCase::Case3)),
        SceneName::LongRange => (
            "long-range",
            long_range(&LongRangeParams {
                seed,
                swap,
                ..LongRangeParams::default()
            }),
        ),
        SceneName::LongRangeEnu => (
            "long-range-enu",
            long_range(&LongRangeParams {
                seed,
                swap,
                ..LongRangeParams::enu()
            }),
        ),
        SceneName::Flat => (
            "flat",
            long_range(&LongRangeParams {
                seed,
                swap,
                ..LongRangeParams::flat()
            }),
        ),
        SceneName::Calibration => (
            "calibration",
            calibration(&CalibrationParams {
                seed,
                ..CalibrationParams::default()
            }),
        ),
        SceneName::Large => (
            "large",
            large(&LargeParams {
                seed,
                ..LargeParams::default()
            }),
        ),
        SceneName::Huge => (
            "huge",
            large(&LargeParams {
                seed,
                ..LargeParams::huge()
            }),
        ),
        SceneName::MonitoringSeries => return monitoring_series(&args),
    };
    let (epoch, truth) = generated.context("generating the scene")?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    let suffix = if args.blunder { "-blunder" } else { "" };
    let stem = format!("{name}{suffix}-seed{seed}");
    for (ext, text) in [
        ("epoch", serde_json::to_string_pretty(&epoch)?),
        ("truth", serde_json::to_string_pretty(&truth)?),
    ] {
        write(args.out_dir.join(format!("{stem}.{ext}.json")), text)?;
    }
    Ok(())
}
