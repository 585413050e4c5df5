//! Sub-pixel centring of large targets from the grey-level gradients: a dual-conic fit (Ouellet &
//! Hébert, "Precise ellipse estimation without contour point extraction", Machine Vision and
//! Applications 21, 2009).
//!
//! Every pixel near the target's edge gives a line through the pixel centre, normal to the image
//! gradient there: `l = (gx, gy, −(gx·x + gy·y))`. The lines of an ellipse's edge are its tangents,
//! and tangent lines satisfy `lᵀ C* l = 0` for the ellipse's dual conic `C*` (eq. 5 of the paper).
//! With `C*₃₃` fixed to 1 this is linear in the other five entries, solved by least squares with
//! each line weighted by its own scale (strong edges count more, flat pixels nothing). The centre
//! is `(C*₁₃, C*₂₃)` (eq. 8). No edge points are extracted and no threshold enters: the fit uses the
//! whole blurred edge, which makes it insensitive to the blur, the JPEG ringing and the grey level
//! chosen to cut the target, all of which bias contour fits.
//!
//! Gradients are 3 × 3 Sobel differences (divided by 8: grey levels per px). The pixels used are
//! those within the region's moment ellipse grown by a margin, so a neighbouring target or the
//! lettering beside one does not enter.

use super::decode::GreyImage;
use nalgebra::{Matrix2, Matrix5, Vector5};

/// Result of a dual-conic fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualConicFit {
    /// Centre (col, row) in px.
    pub centre: [f64; 2],
    /// Semi-axes (major, minor) in px.
    pub semi_axes: [f64; 2],
    /// σ of the centre (col, row) in px for image noise σ 1 grey level (multiply by the noise):
    /// the gradients' noise propagated through each line's equation and the least-squares fit
    /// (before the calibration factor applied by the caller). The fit's own residuals are no
    /// measure of it: they hold the spread of the blurred edge's lines about the one ellipse, which
    /// is symmetric and moves no centre.
    pub sigma_unit: [f64; 2],
    /// Pixels (lines) used.
    pub lines: usize,
}

/// The region to fit: a start centre and the region's central second moments (px²:
/// [μxx, μyy, μxy]), as from the thresholded component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    /// Start centre (col, row) in px.
    pub centre: [f64; 2],
    /// Central second moments [μxx, μyy, μxy] in px².
    pub m2: [f64; 3],
}

/// Margin (px) added around the region's moment ellipse: the blurred edge and the Sobel support.
pub fn margin_px(r_eq: f64) -> f64 {
    3.0 + 0.15 * r_eq
}

/// Fits the dual conic to the gradients within the region's moment ellipse grown by
/// [`margin_px`]; pixels of the window that fall outside the image are left out (a target whose
/// whole edge lies inside the image is measured even at the image border). None if too few
/// lines remain or the result is not an ellipse.
pub fn fit_dual_conic(img: &GreyImage, region: &Region) -> Option<DualConicFit> {
    let [mxx, myy, mxy] = region.m2;
    // a filled ellipse of shape matrix S (semi-axes² as eigenvalues) has moments S / 4
    let s_reg = Matrix2::new(4.0 * mxx, 4.0 * mxy, 4.0 * mxy, 4.0 * myy);
    let det = s_reg.determinant();
    if !(det.is_finite() && det > 0.0 && mxx > 0.0 && myy > 0.0) {
        return None;
    }
    let r_eq = det.sqrt().sqrt();
    let margin = margin_px(r_eq);
    let grow = (1.0 + margin / r_eq).powi(2);
    let s_inv = s_reg.try_inverse()? / grow;
    let c0 = region.centre;
    let ext_x = (4.0 * mxx * grow).sqrt();
    let ext_y = (4.0 * myy * grow).sqrt();
    let (w, h) = (img.width() as i64, img.height() as i64);
    let x0 = ((c0[0] - ext_x).floor() as i64).max(1);
    let x1 = ((c0[0] + ext_x).ceil() as i64).min(w - 2);
    let y0 = ((c0[1] - ext_y).floor() as i64).max(1);
    let y1 = ((c0[1] + ext_y).ceil() as i64).min(h - 2);
    if x1 - x0 < 3 || y1 - y0 < 3 {
        return None;
    }
    let scale = r_eq;
    let data = img.data();
    let wu = w as usize;
    let mut n = Matrix5::<f64>::zeros();
    let mut rhs = Vector5::<f64>::zeros();
    // per line: the equation's row, its right-hand side, the gradient and the normalised offset
    let mut rows: Vec<([f64; 5], f64, [f64; 4])> =
        Vec::with_capacity(((x1 - x0 + 1) * (y1 - y0 + 1)) as usize);
    for y in y0..=y1 {
        let dy = y as f64 - c0[1];
        let (ym, yc, yp) = (
            (y as usize - 1) * wu,
            y as usize * wu,
            (y as usize + 1) * wu,
        );
        for x in x0..=x1 {
            let dx = x as f64 - c0[0];
            let rho2 =
                s_inv[(0, 0)] * dx * dx + 2.0 * s_inv[(0, 1)] * dx * dy + s_inv[(1, 1)] * dy * dy;
            if rho2 > 1.0 {
                continue;
            }
            let xu = x as usize;
            let p = |o: usize, k: usize| f64::from(data[o + k]);
            let gx = (p(ym, xu + 1) - p(ym, xu - 1)
                + 2.0 * (p(yc, xu + 1) - p(yc, xu - 1))
                + p(yp, xu + 1)
                - p(yp, xu - 1))
                / 8.0;
            let gy =
                (p(yp, xu - 1) - p(ym, xu - 1) + 2.0 * (p(yp, xu) - p(ym, xu)) + p(yp, xu + 1)
                    - p(ym, xu + 1))
                    / 8.0;
            if gx == 0.0 && gy == 0.0 {
                continue;
            }
            let (u, v) = (dx / scale, dy / scale);
            let c = -(gx * u + gy * v);
            let row = [gx * gx, gx * gy, gy * gy, gx * c, gy * c];
            let b = -c * c;
            let a = Vector5::from_column_slice(&row);
            n.ger(1.0, &a, &a, 1.0);
            rhs.axpy(b, &a, 1.0);
            rows.push((row, b, [gx, gy, u, v]));
        }
    }
    if rows.len() < 12 {
        return None;
    }
    let ch = n.cholesky()?;
    let t = ch.solve(&rhs);
    let cov = ch.inverse();
    // Noise: each gradient component carries σ_g² = σ_n²·12/64 (Sobel / 8, the two uncorrelated).
    // A line's equation e = lᵀC*l moves by ∂e/∂g = 2(q₁ − u q₃, q₂ − v q₃) with q = C*l, and the
    // least-squares solution by (AᵀA)⁻¹ a δe: cov(t) = (AᵀA)⁻¹ (Σ a aᵀ σ_e²) (AᵀA)⁻¹.
    let c_star = nalgebra::Matrix3::new(
        t[0],
        0.5 * t[1],
        0.5 * t[3],
        0.5 * t[1],
        t[2],
        0.5 * t[4],
        0.5 * t[3],
        0.5 * t[4],
        1.0,
    );
    let var_g = 12.0 / 64.0;
    let mut meat = Matrix5::<f64>::zeros();
    for (a, _, [gx, gy, u, v]) in &rows {
        let l = nalgebra::Vector3::new(*gx, *gy, -(gx * u + gy * v));
        let q = c_star * l;
        let (dx, dy) = (q[0] - u * q[2], q[1] - v * q[2]);
        let var_e = 4.0 * var_g * (dx * dx + dy * dy);
        let a = Vector5::from_column_slice(a);
        meat.ger(var_e, &a, &a, 1.0);
    }
    let cov_noise = cov * meat * cov;
    // C* = [[A, B/2, D/2], [B/2, C, E/2], [D/2, E/2, 1]] = [[c cᵀ − S, c], [cᵀ, 1]]
    let (cu, cv) = (0.5 * t[3], 0.5 * t[4]);
    let s_fit = Matrix2::new(
        cu * cu - t[0],
        cu * cv - 0.5 * t[1],
        cu * cv - 0.5 * t[1],
        cv * cv - t[2],
    );
    let eig = s_fit.symmetric_eigen();
    let (l_big, l_small) = (
        eig.eigenvalues[0].max(eig.eigenvalues[1]),
        eig.eigenvalues[0].min(eig.eigenvalues[1]),
    );
    if !(l_small > 0.0 && l_big.is_finite()) {
        return None;
    }
    let centre = [c0[0] + scale * cu, c0[1] + scale * cv];
    if !(centre[0].is_finite() && centre[1].is_finite()) {
        return None;
    }
    Some(DualConicFit {
        centre,
        semi_axes: [scale * l_big.sqrt(), scale * l_small.sqrt()],
        sigma_unit: [
            scale * 0.5 * cov_noise[(3, 3)].max(0.0).sqrt(),
            scale * 0.5 * cov_noise[(4, 4)].max(0.0).sqrt(),
        ],
        lines: rows.len(),
    })
}

/// Contrast of an ellipse of semi-axes `a ≥ b` px at `centre` (polarity-signed, grey levels): the
/// median of the pixels within `b / 2` of the centre against the median of a ring 2 px wide
/// starting [`margin_px`] outside the major semi-axis (pixels outside the image left out). NaN
/// when either holds no pixel.
pub fn contrast(
    img: &GreyImage,
    polarity: super::Polarity,
    centre: [f64; 2],
    a: f64,
    b: f64,
) -> f64 {
    let r_in = 0.5 * b;
    let r0 = a + margin_px((a * b).sqrt());
    let r1 = r0 + 2.0;
    let (w, h) = (img.width() as i64, img.height() as i64);
    let x0 = ((centre[0] - r1).floor() as i64).max(0);
    let x1 = ((centre[0] + r1).ceil() as i64).min(w - 1);
    let y0 = ((centre[1] - r1).floor() as i64).max(0);
    let y1 = ((centre[1] + r1).ceil() as i64).min(h - 1);
    let (mut inner, mut ring) = (Vec::new(), Vec::new());
    for y in y0..=y1 {
        for x in x0..=x1 {
            let d2 = (x as f64 - centre[0]).powi(2) + (y as f64 - centre[1]).powi(2);
            let v = img.get(x as usize, y as usize);
            if d2 <= r_in * r_in {
                inner.push(v);
            } else if d2 >= r0 * r0 && d2 <= r1 * r1 {
                ring.push(v);
            }
        }
    }
    if inner.is_empty() || ring.is_empty() {
        return f64::NAN;
    }
    let med = |v: &mut Vec<u16>| {
        let m = v.len() / 2;
        f64::from(*v.select_nth_unstable(m).1)
    };
    polarity.sign() * (med(&mut inner) - med(&mut ring))
}
