//! Quantiles of the χ², F and normal distributions for the statistical tests (no external crate):
//! regularized incomplete gamma and beta functions (series and continued fractions, as in Press et al.,
//! *Numerical Recipes*, §6.2 and §6.4) inverted by bisection.

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7, n = 9; relative error < 1e-14).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularized lower incomplete gamma P(a, x).
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        (sum.ln() - x + a * x.ln() - gln).exp().min(1.0)
    } else {
        // Continued fraction for Q(a, x) (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        let q = (-x + a * x.ln() - gln).exp() * h;
        (1.0 - q).clamp(0.0, 1.0)
    }
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let tiny = 1e-300;
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..1000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// Regularized incomplete beta function I_x(a, b).
pub fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let bt = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        bt * beta_cf(a, b, x) / a
    } else {
        1.0 - bt * beta_cf(b, a, 1.0 - x) / b
    }
}

/// CDF of χ²(k) at x.
pub fn chi2_cdf(x: f64, k: f64) -> f64 {
    gamma_p(0.5 * k, 0.5 * x)
}

/// CDF of F(d1, d2) at x; `d2 = ∞` gives χ²(d1)/d1.
pub fn f_cdf(x: f64, d1: f64, d2: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if !d2.is_finite() {
        return chi2_cdf(x * d1, d1);
    }
    beta_inc(0.5 * d1, 0.5 * d2, d1 * x / (d1 * x + d2))
}

fn invert(cdf: impl Fn(f64) -> f64, p: f64) -> f64 {
    let mut hi = 1.0;
    while cdf(hi) < p && hi < 1e12 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 * hi.max(1e-300) {
            break;
        }
    }
    0.5 * (lo + hi)
}

thread_local! {
    /// Quantiles already computed on this thread, by (distribution, p, d1, d2) bits: the analysis
    /// asks for the same few quantiles for every point of every epoch, and each costs a bisection
    /// of ~50 CDF evaluations. A cache of pure values: results are identical with or without it.
    static QUANTILES: std::cell::RefCell<std::collections::HashMap<(u8, u64, u64, u64), f64>> =
        std::cell::RefCell::new(std::collections::HashMap::new());
}

/// Entries kept before the cache is cleared (bounds memory when callers vary the arguments).
const QUANTILE_CACHE_MAX: usize = 4096;

fn cached(kind: u8, p: f64, d1: f64, d2: f64, compute: impl FnOnce() -> f64) -> f64 {
    let key = (kind, p.to_bits(), d1.to_bits(), d2.to_bits());
    if let Some(v) = QUANTILES.with(|c| c.borrow().get(&key).copied()) {
        return v;
    }
    let v = compute();
    QUANTILES.with(|c| {
        let mut c = c.borrow_mut();
        if c.len() >= QUANTILE_CACHE_MAX {
            c.clear();
        }
        c.insert(key, v);
    });
    v
}

/// Quantile of χ²(k) at probability p (e.g. `chi2_quantile(0.99, 3.0)` = 11.345).
pub fn chi2_quantile(p: f64, k: f64) -> f64 {
    cached(0, p, k, 0.0, || invert(|x| chi2_cdf(x, k), p))
}

/// Quantile of F(d1, d2) at probability p; `d2 = f64::INFINITY` for a known variance factor.
pub fn f_quantile(p: f64, d1: f64, d2: f64) -> f64 {
    cached(1, p, d1, d2, || invert(|x| f_cdf(x, d1, d2), p))
}

/// CDF of the non-central χ²(k, λ) at x: the Poisson(λ/2) mixture of central χ²(k + 2j), summed
/// outwards from the Poisson mode until the weights fall below 1e-14.
pub fn noncentral_chi2_cdf(x: f64, k: f64, lambda: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if lambda <= 0.0 {
        return chi2_cdf(x, k);
    }
    let half = 0.5 * lambda;
    let mode = half.floor();
    let weight = |j: f64| (-half + j * half.ln() - ln_gamma(j + 1.0)).exp();
    let (mut total, mut mass) = (0.0, 0.0);
    let mut j = mode;
    loop {
        let w = weight(j);
        total += w * chi2_cdf(x, k + 2.0 * j);
        mass += w;
        if (w < 1e-14 && j > mode) || j > mode + 10_000.0 {
            break;
        }
        j += 1.0;
    }
    let mut j = mode - 1.0;
    while j >= 0.0 {
        let w = weight(j);
        total += w * chi2_cdf(x, k + 2.0 * j);
        mass += w;
        if w < 1e-14 {
            break;
        }
        j -= 1.0;
    }
    (total / mass.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0)
}

/// The non-centrality λ at which a test with `k` degrees of freedom and critical value
/// `critical` detects with probability `power`: P(χ'²(k, λ) > critical) = power (cached like
/// the quantiles: every point of a page asks for the same one).
pub fn noncentrality_for_power(critical: f64, k: f64, power: f64) -> f64 {
    cached(2, power, critical, k, || {
        invert(
            |lambda| 1.0 - noncentral_chi2_cdf(critical, k, lambda),
            power,
        )
    })
}

/// Quantile of the standard normal distribution at probability p (one-sided).
pub fn normal_quantile(p: f64) -> f64 {
    if p == 0.5 {
        return 0.0;
    }
    let z = chi2_quantile((2.0 * p - 1.0).abs(), 1.0).sqrt();
    if p > 0.5 {
        z
    } else {
        -z
    }
}

/// The usable epochs of a series along one direction as weighted rows `(t, d, w)`: time (days),
/// displacement (mm) and weight 1/σ² (1/mm²), oldest first; epochs with a non-finite value or
/// a σ that is not positive are left out.
pub fn weighted_rows(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64]) -> Vec<(f64, f64, f64)> {
    let mut rows: Vec<(f64, f64, f64)> = t_days
        .iter()
        .zip(d_mm)
        .zip(sigma_mm)
        .filter(|((t, d), s)| t.is_finite() && d.is_finite() && s.is_finite() && **s > 0.0)
        .map(|((&t, &d), &s)| (t, d, 1.0 / (s * s)))
        .collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        assert!((chi2_quantile(0.99, 3.0) - 11.3449).abs() < 1e-3);
        assert!((chi2_quantile(0.95, 1.0) - 3.8415).abs() < 1e-3);
        assert!((f_quantile(0.95, 3.0, 10.0) - 3.7083).abs() < 1e-3);
        assert!((normal_quantile(0.99) - 2.3263).abs() < 1e-3);
        assert!((normal_quantile(0.01) + 2.3263).abs() < 1e-3);
    }

    #[test]
    fn noncentral_chi2_is_central_at_zero_and_meets_the_power_table() {
        // The central CDF at λ = 0, smaller for λ > 0, and the tabulated power point
        // P(χ'²(1, (1.95996 + 0.84162)²) > 3.8415) = 0.80 (α = 5 %, power 80 %).
        for x in [1.0, 5.0, 11.34] {
            assert!((noncentral_chi2_cdf(x, 3.0, 0.0) - chi2_cdf(x, 3.0)).abs() < 1e-12);
            assert!(noncentral_chi2_cdf(x, 3.0, 4.0) < chi2_cdf(x, 3.0));
        }
        let lambda = noncentrality_for_power(chi2_quantile(0.95, 1.0), 1.0, 0.8);
        assert!((lambda - 7.849).abs() < 0.01, "{lambda}");
    }
}
