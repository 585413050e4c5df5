//! Sub-pixel centring of large targets: least-squares fit of a blurred-ellipse model to the grey
//! values of a window (Levenberg–Marquardt).
//!
//! Model of the signal at a pixel centre `v = p − c`:
//! `I = B + bx·vx + by·vy + A·Φ(d / s)`, where `Φ` is the normal CDF, `s` the edge blur σ (optics and
//! pixel integration) and `d ≈ (1 − ρ)·ρ / |Q v|` the signed distance to the ellipse
//! `ρ² = vᵀ Q v = 1` (positive inside). The ellipse is parametrised by its conic matrix `Q`, which stays
//! well-conditioned for circles (unlike semi-axes and an angle). All the centre information of a
//! flat-topped target is in its edge: this fit uses it at the noise limit, while a windowed centroid also
//! weights the interior noise.

use super::decode::GreyImage;
use super::target::Polarity;
use nalgebra::{SMatrix, SVector};

const NP: usize = 10;
type Par = SVector<f64, NP>;

/// Result of an ellipse fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipseFit {
    /// Centre (col, row) in px.
    pub centre: [f64; 2],
    /// Semi-axes (major, minor) in px.
    pub semi_axes: [f64; 2],
    /// Edge blur σ in px.
    pub blur: f64,
    /// Amplitude (target over background) in grey levels, signed by polarity to be positive.
    pub amplitude: f64,
    /// Propagated σ of each centre coordinate in px (from the fit's residual σ).
    pub sigma_px: f64,
}

/// Standard normal CDF Φ(x) (erfc-based, |error| < 1.2e-7).
fn phi(x: f64) -> f64 {
    let z = -x / std::f64::consts::SQRT_2;
    // Numerical Recipes erfc (Chebyshev)
    let t = 1.0 / (1.0 + 0.5 * z.abs());
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    let erfc = if z >= 0.0 { r } else { 2.0 - r };
    0.5 * erfc
}

/// Signed distance to the edge over the blur, `d / s`, at (x, y).
fn edge_arg(p: &Par, x: f64, y: f64) -> f64 {
    let (vx, vy) = (x - p[0], y - p[1]);
    let (qx, qy) = (p[2] * vx + p[3] * vy, p[3] * vx + p[4] * vy);
    let rho = (vx * qx + vy * qy).max(0.0).sqrt();
    let g = qx.hypot(qy);
    let d = if g > 1e-12 {
        (1.0 - rho) * rho / g
    } else {
        1.0 / p[2].max(p[4]).max(1e-9).sqrt()
    };
    d / p[5].max(0.05)
}

/// p = [cx, cy, q11, q12, q22, s, A, B, bx, by] (offsets relative to the window origin `o`).
fn model(p: &Par, x: f64, y: f64) -> f64 {
    let (vx, vy) = (x - p[0], y - p[1]);
    let (qx, qy) = (p[2] * vx + p[3] * vy, p[3] * vx + p[4] * vy);
    let rho2 = (vx * qx + vy * qy).max(0.0);
    let rho = rho2.sqrt();
    let g = qx.hypot(qy);
    let d = if g > 1e-12 {
        (1.0 - rho) * rho / g
    } else {
        // centre: distance to the edge along the shortest axis
        1.0 / p[2].max(p[4]).max(1e-9).sqrt()
    };
    p[7] + p[8] * vx + p[9] * vy + p[6] * phi(d / p[5].max(0.05))
}

/// Fits the blurred-ellipse model in a square window of half-size `half` px around `c0`, starting
/// from radius `r0` px. None if the window leaves the image, the fit fails or leaves its bounds.
pub fn fit_ellipse(
    img: &GreyImage,
    polarity: Polarity,
    c0: [f64; 2],
    r0: f64,
    half: f64,
) -> Option<EllipseFit> {
    if !(r0.is_finite() && r0 > 0.5 && half.is_finite() && half > r0) {
        return None;
    }
    let sign = match polarity {
        Polarity::BrightOnDark => 1.0,
        Polarity::DarkOnBright => -1.0,
    };
    let (w, h) = (img.width() as f64, img.height() as f64);
    if c0[0] - half < 0.0 || c0[1] - half < 0.0 || c0[0] + half > w - 1.0 || c0[1] + half > h - 1.0
    {
        return None;
    }
    let (x0, x1) = (
        (c0[0] - half).ceil() as usize,
        (c0[0] + half).floor() as usize,
    );
    let (y0, y1) = (
        (c0[1] - half).ceil() as usize,
        (c0[1] + half).floor() as usize,
    );
    let o = [x0 as f64, y0 as f64];
    let mut pix = Vec::with_capacity((x1 - x0 + 1) * (y1 - y0 + 1));
    for y in y0..=y1 {
        for x in x0..=x1 {
            pix.push((
                x as f64 - o[0],
                y as f64 - o[1],
                sign * img.get(x, y) as f64,
            ));
        }
    }
    // start: background from the window border, amplitude from the centre pixel
    let mut border: Vec<f64> = pix
        .iter()
        .filter(|p| p.0 == 0.0 || p.1 == 0.0 || p.0 == (x1 - x0) as f64 || p.1 == (y1 - y0) as f64)
        .map(|p| p.2)
        .collect();
    border.sort_by(|a, b| a.total_cmp(b));
    let b0 = border[border.len() / 2];
    let cpx = (c0[0].round() as usize, c0[1].round() as usize);
    let a0 = sign * img.get(cpx.0, cpx.1) as f64 - b0;
    if a0 <= 0.0 {
        return None;
    }
    let q0 = 1.0 / (r0 * r0);
    let mut p = Par::from_column_slice(&[
        c0[0] - o[0],
        c0[1] - o[1],
        q0,
        0.0,
        q0,
        0.8,
        a0,
        b0,
        0.0,
        0.0,
    ]);
    let steps = |p: &Par| -> Par {
        let sc = p[2].abs().max(p[4].abs()).max(1e-6);
        Par::from_column_slice(&[
            1e-4,
            1e-4,
            sc * 1e-4,
            sc * 1e-4,
            sc * 1e-4,
            1e-4,
            1e-3 * p[6].abs().max(1.0),
            1e-3 * p[6].abs().max(1.0),
            1e-6 * p[6].abs().max(1.0),
            1e-6 * p[6].abs().max(1.0),
        ])
    };
    let cost = |p: &Par| -> f64 {
        pix.iter()
            .map(|&(x, y, z)| {
                let r = z - model(p, x, y);
                r * r
            })
            .sum()
    };
    let mut lambda = 1e-3;
    let mut c_cur = cost(&p);
    let mut n_final = SMatrix::<f64, NP, NP>::zeros();
    let mut converged = false;
    for _ in 0..30 {
        if converged {
            break;
        }
        let st = steps(&p);
        let mut n = SMatrix::<f64, NP, NP>::zeros();
        let mut g = Par::zeros();
        for &(x, y, z) in &pix {
            let f0 = model(&p, x, y);
            let mut j = Par::zeros();
            let t = edge_arg(&p, x, y);
            if t.abs() > 4.5 {
                // far from the edge: only amplitude and background act (Φ is 0 or 1 there)
                let (vx, vy) = (x - p[0], y - p[1]);
                j[6] = if t > 0.0 { 1.0 } else { 0.0 };
                j[7] = 1.0;
                j[8] = vx;
                j[9] = vy;
                n += j * j.transpose();
                g += j * (z - f0);
                continue;
            }
            for k in 0..NP {
                let mut pp = p;
                pp[k] += st[k];
                j[k] = (model(&pp, x, y) - f0) / st[k];
            }
            n += j * j.transpose();
            g += j * (z - f0);
        }
        n_final = n;
        let mut improved = false;
        for _ in 0..8 {
            let mut nd = n;
            for k in 0..NP {
                nd[(k, k)] *= 1.0 + lambda;
            }
            let Some(ch) = nd.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dp = ch.solve(&g);
            let pn = p + dp;
            let cn = cost(&pn);
            if cn.is_finite() && cn <= c_cur && pn[5] > 0.05 {
                let small = dp[0].abs() + dp[1].abs() < 1e-5;
                p = pn;
                c_cur = cn;
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                converged = small;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    // validity: positive-definite conic, centre near the start, sensible size and blur
    let det = p[2] * p[4] - p[3] * p[3];
    if !(p[2] > 0.0 && p[4] > 0.0 && det > 0.0 && p[6] > 0.0 && p[5] < 0.5 * r0 + 2.0) {
        return None;
    }
    let tr = p[2] + p[4];
    let disc = (0.25 * (p[2] - p[4]).powi(2) + p[3] * p[3]).sqrt();
    let (l_small, l_big) = (0.5 * tr - disc, 0.5 * tr + disc);
    if l_small <= 0.0 {
        return None;
    }
    let semi = [1.0 / l_small.sqrt(), 1.0 / l_big.sqrt()];
    let centre = [p[0] + o[0], p[1] + o[1]];
    if (centre[0] - c0[0]).hypot(centre[1] - c0[1]) > 0.5 * r0 + 1.0
        || semi[0] > half
        || !centre[0].is_finite()
        || !centre[1].is_finite()
    {
        return None;
    }
    let dof = (pix.len() as f64 - NP as f64).max(1.0);
    let s0 = (c_cur / dof).sqrt();
    let sigma_px = n_final
        .try_inverse()
        .map(|c| (0.5 * (c[(0, 0)] + c[(1, 1)])).max(0.0).sqrt() * s0)
        .unwrap_or(f64::NAN);
    Some(EllipseFit {
        centre,
        semi_axes: semi,
        blur: p[5],
        amplitude: p[6],
        sigma_px,
    })
}
