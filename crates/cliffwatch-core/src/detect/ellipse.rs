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
//!
//! The Jacobian is analytic (one model evaluation per pixel and iteration, shared with the residual
//! sum of squares). Light that does not belong to the target — a glint or a neighbouring blob
//! touching it — is kept out in two steps: the fit starts from the largest disc inscribed in the
//! half-amplitude region (the target, not the centroid of target and glint) and leaves out the bright
//! pixels outside that disc whose point reflection through its centre is dark (an ellipse is
//! point-symmetric, a glint beside it is not); after each fit, pixels with excess signal beyond 4
//! robust σ (grown by one pixel) are masked and the fit repeated until the mask settles.

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

/// Standard normal CDF Φ(x) and density φ(x) together, from one exponential (Abramowitz & Stegun
/// 26.2.17, |error of Φ| < 7.5e-8).
#[inline]
pub fn normal_cdf_pdf(x: f64) -> (f64, f64) {
    let pdf = 0.398_942_280_401_432_7 * (-0.5 * x * x).exp();
    let k = 1.0 / (1.0 + 0.231_641_9 * x.abs());
    let poly = k
        * (0.319_381_530
            + k * (-0.356_563_782
                + k * (1.781_477_937 + k * (-1.821_255_978 + k * 1.330_274_429))));
    let tail = pdf * poly;
    (if x >= 0.0 { 1.0 - tail } else { tail }, pdf)
}

/// Standard normal CDF Φ(x) (see [`normal_cdf_pdf`]).
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    normal_cdf_pdf(x).0
}

/// Model value and its gradient with respect to the parameters at (x, y).
///
/// p = [cx, cy, q11, q12, q22, s, A, B, bx, by] (offsets relative to the window origin).
/// Near the centre (ρ < 1e-3) the geometric derivatives are set to zero: there `t = d / s` is far
/// inside the target and Φ is flat.
#[inline]
fn model_grad(p: &Par, x: f64, y: f64) -> (f64, Par) {
    let (vx, vy) = (x - p[0], y - p[1]);
    let (qx, qy) = (p[2] * vx + p[3] * vy, p[3] * vx + p[4] * vy);
    let rho = (vx * qx + vy * qy).max(0.0).sqrt();
    let g = (qx * qx + qy * qy).sqrt();
    let s = p[5].max(0.05);
    let mut j = Par::zeros();
    j[7] = 1.0;
    j[8] = vx;
    j[9] = vy;
    j[0] = -p[8];
    j[1] = -p[9];
    if rho < 1e-3 || g < 1e-12 {
        // centre: distance to the edge along the shortest axis
        let t = 1.0 / (p[2].max(p[4]).max(1e-9).sqrt() * s);
        let ph = normal_cdf(t);
        j[6] = ph;
        return (p[7] + p[8] * vx + p[9] * vy + p[6] * ph, j);
    }
    let d = (1.0 - rho) * rho / g;
    let t = d / s;
    let (ph, dens) = normal_cdf_pdf(t);
    j[6] = ph;
    let f = p[7] + p[8] * vx + p[9] * vy + p[6] * ph;
    if t.abs() > 6.0 {
        return (f, j);
    }
    // f = … + A·Φ(d/s): ∂f/∂θ = A·φ(t)·(∂d/∂θ)/s, ∂d = ((1 − 2ρ)∂ρ − d·∂g)/g
    let k = p[6] * dens / s;
    let a = (1.0 - 2.0 * rho) / g;
    let b = d / g;
    let (irho, ig) = (1.0 / rho, 1.0 / g);
    // ∂ρ/∂c = −Qv/ρ, ∂g/∂c = −Q(Qv)/g
    let drho = [-qx * irho, -qy * irho];
    let dg = [-(p[2] * qx + p[3] * qy) * ig, -(p[3] * qx + p[4] * qy) * ig];
    j[0] += k * (a * drho[0] - b * dg[0]);
    j[1] += k * (a * drho[1] - b * dg[1]);
    // ∂ρ/∂q = (vx², 2·vx·vy, vy²)/(2ρ); ∂g/∂q = (qx·vx, qx·vy + qy·vx, qy·vy)/g
    let hr = 0.5 * irho;
    j[2] = k * (a * vx * vx * hr - b * qx * vx * ig);
    j[3] = k * (a * 2.0 * vx * vy * hr - b * (qx * vy + qy * vx) * ig);
    j[4] = k * (a * vy * vy * hr - b * qy * vy * ig);
    if p[5] > 0.05 {
        j[5] = -k * t;
    }
    (f, j)
}

/// Model value at (x, y) (see [`model_grad`]).
#[inline]
fn model(p: &Par, x: f64, y: f64) -> f64 {
    let (vx, vy) = (x - p[0], y - p[1]);
    let (qx, qy) = (p[2] * vx + p[3] * vy, p[3] * vx + p[4] * vy);
    let rho2 = (vx * qx + vy * qy).max(0.0);
    let rho = rho2.sqrt();
    let g = (qx * qx + qy * qy).sqrt();
    let d = if rho >= 1e-3 && g > 1e-12 {
        (1.0 - rho) * rho / g
    } else {
        // centre: distance to the edge along the shortest axis
        1.0 / p[2].max(p[4]).max(1e-9).sqrt()
    };
    p[7] + p[8] * vx + p[9] * vy + p[6] * normal_cdf(d / p[5].max(0.05))
}

/// Pixels of a fit window: (x, y, polarity-signed grey level), row-major.
type Pixels = [(f64, f64, f64)];

/// Levenberg–Marquardt on the pixels with `keep[i]`, from `p` (at most 30 iterations, until the
/// centre moves less than 1e-5 px). Each trial point costs one pass: the residual sum of squares,
/// normal matrix and gradient are accumulated together. Returns the parameters, the residual sum of
/// squares and the normal matrix at them.
fn levenberg_marquardt(
    mut p: Par,
    pix: &Pixels,
    keep: &[bool],
) -> (Par, f64, SMatrix<f64, NP, NP>) {
    let accumulate = |p: &Par| -> (f64, SMatrix<f64, NP, NP>, Par) {
        let mut n = SMatrix::<f64, NP, NP>::zeros();
        let mut g = Par::zeros();
        let mut cost = 0.0;
        for (&(x, y, z), _) in pix.iter().zip(keep).filter(|(_, k)| **k) {
            let (f0, j) = model_grad(p, x, y);
            let r = z - f0;
            cost += r * r;
            n.ger(1.0, &j, &j, 1.0);
            g.axpy(r, &j, 1.0);
        }
        (cost, n, g)
    };
    let mut lambda = 1e-3;
    let (mut c_cur, mut n, mut g) = accumulate(&p);
    for _ in 0..30 {
        let mut improved = false;
        let mut converged = false;
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
            if pn[5] <= 0.05 {
                lambda *= 10.0;
                continue;
            }
            let (cn, nn, gn) = accumulate(&pn);
            if cn.is_finite() && cn <= c_cur {
                converged = dp[0].abs() + dp[1].abs() < 1e-5;
                (p, c_cur, n, g) = (pn, cn, nn, gn);
                lambda = (lambda * 0.3).max(1e-9);
                improved = true;
                break;
            }
            lambda *= 10.0;
        }
        if !improved || converged {
            break;
        }
    }
    (p, c_cur, n)
}

/// Residuals beyond this many robust σ (1.4826 × median |residual|) mark a pixel as an outlier.
const OUTLIER_SIGMA: f64 = 4.0;
/// Pixels within this many px (square neighbourhood) of an outlier are masked too: the blurred
/// fringe of a glint is not yet an outlier but still pulls.
const GROW: usize = 1;
/// Most rounds of outlier masking after the first fit.
const OUTLIER_ROUNDS: usize = 3;

/// Fits the pixels of `keep`, then masks outliers over the whole window — pixels whose excess
/// signal (positive residual) exceeds [`OUTLIER_SIGMA`] robust σ, grown by [`GROW`] px — and refits, until the mask settles. The mask is recomputed from each fit, so
/// edge pixels masked while the fit was still pulled come back. None when more than 40 % of the
/// window would be masked. Returns the parameters, residual sum of squares, normal matrix and the
/// count of pixels used.
fn robust_fit(
    p0: Par,
    pix: &Pixels,
    nx: usize,
    mut keep: Vec<bool>,
) -> Option<(Par, f64, SMatrix<f64, NP, NP>, usize)> {
    let (mut p, mut c, mut n) = levenberg_marquardt(p0, pix, &keep);
    let ny = pix.len() / nx;
    for _ in 0..OUTLIER_ROUNDS {
        let res: Vec<f64> = pix.iter().map(|&(x, y, z)| z - model(&p, x, y)).collect();
        let mut abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
        // only excess signal is an outlier: a glint or a neighbour adds light
        let mid = abs.len() / 2;
        let mad = *abs.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        let lim = OUTLIER_SIGMA * 1.4826 * mad.max(1e-12);
        let mut next = vec![true; pix.len()];
        for (i, r) in res.iter().enumerate() {
            if *r > lim {
                let (ix, iy) = (i % nx, i / nx);
                for yy in iy.saturating_sub(GROW)..=(iy + GROW).min(ny - 1) {
                    for xx in ix.saturating_sub(GROW)..=(ix + GROW).min(nx - 1) {
                        next[yy * nx + xx] = false;
                    }
                }
            }
        }
        if next == keep {
            break;
        }
        let used = next.iter().filter(|k| **k).count();
        if (used as f64) < 0.6 * pix.len() as f64 {
            return None;
        }
        keep = next;
        (p, c, n) = levenberg_marquardt(p, pix, &keep);
    }
    let used = keep.iter().filter(|k| **k).count();
    Some((p, c, n, used))
}

/// The largest disc inscribed in the region `z > level` of the window (chamfer 3-4 distance to the
/// nearest pixel outside), among pixels within `r0` of `near`: its centre (window px, the mean of the
/// pixels at the largest distance) and radius (px). None if no pixel is inside.
fn inscribed_disc(
    pix: &Pixels,
    nx: usize,
    level: f64,
    near: [f64; 2],
    r0: f64,
) -> Option<([f64; 2], f64)> {
    let ny = pix.len() / nx;
    const INF: u32 = u32::MAX / 2;
    let mut d: Vec<u32> = pix
        .iter()
        .map(|p| if p.2 > level { INF } else { 0 })
        .collect();
    let at = |d: &[u32], x: isize, y: isize| -> u32 {
        if x < 0 || y < 0 || x >= nx as isize || y >= ny as isize {
            0
        } else {
            d[y as usize * nx + x as usize]
        }
    };
    for y in 0..ny as isize {
        for x in 0..nx as isize {
            let i = y as usize * nx + x as usize;
            if d[i] == 0 {
                continue;
            }
            let m = (at(&d, x - 1, y) + 3)
                .min(at(&d, x - 1, y - 1) + 4)
                .min(at(&d, x, y - 1) + 3)
                .min(at(&d, x + 1, y - 1) + 4);
            d[i] = d[i].min(m);
        }
    }
    for y in (0..ny as isize).rev() {
        for x in (0..nx as isize).rev() {
            let i = y as usize * nx + x as usize;
            if d[i] == 0 {
                continue;
            }
            let m = (at(&d, x + 1, y) + 3)
                .min(at(&d, x + 1, y + 1) + 4)
                .min(at(&d, x, y + 1) + 3)
                .min(at(&d, x - 1, y + 1) + 4);
            d[i] = d[i].min(m);
        }
    }
    let r2 = r0 * r0;
    let near_ok = |i: usize| {
        let (x, y) = (pix[i].0, pix[i].1);
        (x - near[0]).powi(2) + (y - near[1]).powi(2) <= r2
    };
    let best = (0..pix.len()).filter(|&i| near_ok(i)).map(|i| d[i]).max()?;
    if best == 0 {
        return None;
    }
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for i in (0..pix.len()).filter(|&i| near_ok(i) && d[i] == best) {
        sx += pix[i].0;
        sy += pix[i].1;
        n += 1.0;
    }
    Some(([sx / n, sy / n], best as f64 / 3.0 + 0.5))
}

/// The pixels of the square window of half-width `half` px about `c0` (which lies inside the
/// image): `(x, y, value)` with x, y relative to the window's top-left pixel and the value signed so
/// that the target is bright; row-major, with the row length and the window's origin (px).
fn window(
    img: &GreyImage,
    c0: [f64; 2],
    half: f64,
    sign: f64,
) -> (Vec<(f64, f64, f64)>, usize, [f64; 2]) {
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
    (pix, x1 - x0 + 1, o)
}

/// The median value of the window's border pixels: the background's start value.
fn border_median(pix: &[(f64, f64, f64)], nx: usize) -> f64 {
    let (last_x, last_y) = ((nx - 1) as f64, (pix.len() / nx - 1) as f64);
    let mut border: Vec<f64> = pix
        .iter()
        .filter(|p| p.0 == 0.0 || p.1 == 0.0 || p.0 == last_x || p.1 == last_y)
        .map(|p| p.2)
        .collect();
    border.sort_by(|a, b| a.total_cmp(b));
    border[border.len() / 2]
}

/// The pixels the first fit uses: an ellipse is point-symmetric about its centre, so a pixel
/// brighter than `level` outside the start disc (centre `cs`, radius `rs`, window px) whose
/// reflection through `cs` is not bright belongs to something else (a glint, a neighbour); it and
/// its neighbours within `GROW` px are left out.
fn symmetric_core(
    pix: &[(f64, f64, f64)],
    nx: usize,
    cs: [f64; 2],
    rs: f64,
    level: f64,
) -> Vec<bool> {
    let ny = pix.len() / nx;
    let bright = |i: usize| pix[i].2 > level;
    let outside = |i: usize| (pix[i].0 - cs[0]).hypot(pix[i].1 - cs[1]) > rs + 0.5;
    let mut core = vec![true; pix.len()];
    for i in 0..pix.len() {
        if !(bright(i) && outside(i)) {
            continue;
        }
        let (rx, ry) = (
            (2.0 * cs[0] - pix[i].0).round(),
            (2.0 * cs[1] - pix[i].1).round(),
        );
        let mirrored_bright = rx >= 0.0
            && ry >= 0.0
            && (rx as usize) < nx
            && (ry as usize) < ny
            && bright(ry as usize * nx + rx as usize);
        if !mirrored_bright {
            let (ix, iy) = (i % nx, i / nx);
            for yy in iy.saturating_sub(GROW)..=(iy + GROW).min(ny - 1) {
                for xx in ix.saturating_sub(GROW)..=(ix + GROW).min(nx - 1) {
                    core[yy * nx + xx] = false;
                }
            }
        }
    }
    core
}

/// Semi-axes (major, minor; px) of the conic `a x² + 2 b x y + c y² = 1`; None unless it is an
/// ellipse.
fn semi_axes(a: f64, b: f64, c: f64) -> Option<[f64; 2]> {
    let tr = a + c;
    let disc = (0.25 * (a - c).powi(2) + b * b).sqrt();
    let (l_small, l_big) = (0.5 * tr - disc, 0.5 * tr + disc);
    if l_small <= 0.0 {
        return None;
    }
    Some([1.0 / l_small.sqrt(), 1.0 / l_big.sqrt()])
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
    let sign = polarity.sign();
    let (w, h) = (img.width() as f64, img.height() as f64);
    if c0[0] - half < 0.0 || c0[1] - half < 0.0 || c0[0] + half > w - 1.0 || c0[1] + half > h - 1.0
    {
        return None;
    }
    let (pix, nx, o) = window(img, c0, half, sign);
    // start: background from the window border, amplitude from the centre pixel
    let b0 = border_median(&pix, nx);
    let cpx = (c0[0].round() as usize, c0[1].round() as usize);
    let a0 = sign * img.get(cpx.0, cpx.1) as f64 - b0;
    if a0 <= 0.0 {
        return None;
    }
    // start: the largest disc inscribed in the half-amplitude region near the start — the target
    // itself even when a glint or a neighbour touches it and pulls the centroid
    let (cs, rs) = inscribed_disc(&pix, nx, b0 + 0.5 * a0, [c0[0] - o[0], c0[1] - o[1]], r0)
        .unwrap_or(([c0[0] - o[0], c0[1] - o[1]], r0));
    let q0 = 1.0 / (rs * rs);
    let p = Par::from_column_slice(&[cs[0], cs[1], q0, 0.0, q0, 0.8, a0, b0, 0.0, 0.0]);
    // first fit without the asymmetric bright parts (glints, neighbours)
    let core = symmetric_core(&pix, nx, cs, rs, b0 + 0.5 * a0);
    let (p, c_cur, n_final, used) = robust_fit(p, &pix, nx, core)?;

    // validity: positive-definite conic, centre near the start, sensible size and blur
    let det = p[2] * p[4] - p[3] * p[3];
    if !(p[2] > 0.0 && p[4] > 0.0 && det > 0.0 && p[6] > 0.0 && p[5] < 0.5 * r0 + 2.0) {
        return None;
    }
    let semi = semi_axes(p[2], p[3], p[4])?;
    let centre = [p[0] + o[0], p[1] + o[1]];
    if (centre[0] - c0[0]).hypot(centre[1] - c0[1]) > 0.5 * r0 + 1.0
        || semi[0] > half
        || !centre[0].is_finite()
        || !centre[1].is_finite()
    {
        return None;
    }
    let dof = (used as f64 - NP as f64).max(1.0);
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
