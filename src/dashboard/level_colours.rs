//! The alert levels' colours, checked: the stylesheet (badges, plan, server-drawn plots) and the
//! plot script use the same three, and they stay apart for the common colour-vision deficiencies.
//! Watch is Okabe–Ito orange `#E69F00`, warning Okabe–Ito vermillion `#D55E00`, alarm Paul
//! Tol's wine `#882255`: light to dark as the level rises, so they differ in lightness too (and in
//! print). The colours before them (`#b8860b`, `#e8730c`, `#c0392b`) came within ΔE 2 of each
//! other for a deuteranope.
//!
//! Distinctness is the CIE76 ΔE in CIELAB between each pair after simulating protanopia,
//! deuteranopia and tritanopia with the matrices of Machado, Oliveira and Fernandes (2009,
//! severity 1.0) on linear sRGB.

/// `(level, colour)`: the levels' colours as `#RRGGBB`.
pub const LEVEL_COLOURS: [(&str, &str); 3] = [
    ("watch", "#E69F00"),
    ("warning", "#D55E00"),
    ("alarm", "#882255"),
];

/// Least ΔE (CIE76) between two levels' colours under any simulated deficiency.
pub const MIN_DELTA_E: f64 = 15.0;

type M3 = [[f64; 3]; 3];

/// Machado et al. (2009), severity 1.0: protanopia, deuteranopia, tritanopia; and none.
const VISION: [(&str, M3); 4] = [
    (
        "normal",
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    ),
    (
        "protanopia",
        [
            [0.152286, 1.052583, -0.204868],
            [0.114503, 0.786281, 0.099216],
            [-0.003882, -0.048116, 1.051998],
        ],
    ),
    (
        "deuteranopia",
        [
            [0.367322, 0.860646, -0.227968],
            [0.280085, 0.672501, 0.047413],
            [-0.011820, 0.042940, 0.968881],
        ],
    ),
    (
        "tritanopia",
        [
            [1.255528, -0.076749, -0.178779],
            [-0.078411, 0.930809, 0.147602],
            [0.004733, 0.691367, 0.303900],
        ],
    ),
];

/// `#RRGGBB` as linear sRGB in [0, 1].
fn linear(hex: &str) -> [f64; 3] {
    let c = |i: usize| {
        let v = u8::from_str_radix(&hex[i..i + 2], 16).unwrap_or(0) as f64 / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    [c(1), c(3), c(5)]
}

/// CIELAB (D65) of linear sRGB, clamped into the gamut.
fn lab(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb.map(|v| v.clamp(0.0, 1.0));
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
    let f = |t: f64| {
        if t > 0.008856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    };
    [
        116.0 * f(y) - 16.0,
        500.0 * (f(x) - f(y)),
        200.0 * (f(y) - f(z)),
    ]
}

/// ΔE (CIE76) between colours `a` and `b` as seen with vision `m`.
fn delta_e(a: &str, b: &str, m: &M3) -> f64 {
    let seen = |hex: &str| {
        let c = linear(hex);
        lab([0, 1, 2].map(|i| m[i][0] * c[0] + m[i][1] * c[1] + m[i][2] * c[2]))
    };
    let (p, q) = (seen(a), seen(b));
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair of levels stays at least [`MIN_DELTA_E`] apart for each vision, and the
    /// colours used before did not (the "watch and warning look alike").
    #[test]
    fn the_levels_stay_apart_for_colour_blind_readers() {
        for (vision, m) in &VISION {
            for i in 0..3 {
                for j in i + 1..3 {
                    let (a, b) = (LEVEL_COLOURS[i], LEVEL_COLOURS[j]);
                    let d = delta_e(a.1, b.1, m);
                    assert!(d >= MIN_DELTA_E, "{vision}: {} vs {}: ΔE {d:.1}", a.0, b.0);
                }
            }
        }
        let old = ["#b8860b", "#e8730c", "#c0392b"];
        let worst = VISION
            .iter()
            .map(|(_, m)| delta_e(old[0], old[1], m))
            .fold(f64::INFINITY, f64::min);
        assert!(worst < 5.0, "the old watch/warning pair: ΔE {worst:.1}");
    }

    /// The stylesheet and the plot script use exactly these colours for the levels.
    #[test]
    fn the_stylesheet_and_the_plot_script_use_them() {
        let css = include_str!("assets/dashboard.css");
        let js = include_str!("assets/plots.js");
        for (level, colour) in LEVEL_COLOURS {
            assert!(
                css.contains(&format!("--{level}: {colour};")),
                "css {level}"
            );
            assert!(js.contains(&format!("{level}: \"{colour}\"")), "js {level}");
        }
    }
}
