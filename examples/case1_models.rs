//! Paper case 1 (two images, c fixed): index 3 of the orthogonal and the central model on the same
//! data, to check the spec's figure (≈ 0.05–0.06 mm) against an independent rigorous model.
//!
//! `cargo run --example case1_models`

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, Model};
use cliffwatch_sim::scenes::{paper_table1, PaperCase, PaperParams};

fn main() {
    println!("| seed | orthogonal index 3 (mm) | central index 3 (mm) |");
    println!("|---|---|---|");
    for seed in [101, 102, 103, 1, 2, 3, 4, 5] {
        let (epoch, truth) =
            paper_table1(&PaperParams::case(PaperCase::Case1, seed)).expect("scene");
        let mut row = format!("| {seed} |");
        for model in [Model::Orthogonal, Model::Central] {
            let opts = AdjustOptions {
                model,
                ..AdjustOptions::default()
            };
            let cell = match adjust(&epoch, &opts) {
                Ok(a) => truth
                    .index3_rmse_mm(&a.points)
                    .map_or_else(|e| e.to_string(), |v| format!("{:.3}", v[3])),
                Err(e) => format!("error: {e}"),
            };
            row.push_str(&format!(" {cell} |"));
        }
        println!("{row}");
    }
}
