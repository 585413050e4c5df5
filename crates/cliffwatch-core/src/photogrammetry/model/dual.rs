//! Forward-mode automatic differentiation: a value with its gradient with respect to N unknowns.
//!
//! The projection models are written once, generic over [`Scalar`], and evaluated with `f64` for
//! residuals and with [`Dual`] for exact Jacobians (no hand-derived derivative can miss a term, see the
//! note on eqs (15)–(16) in `docs/model.md`).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic a projection model needs.
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + From<f64>
{
    /// The value without derivatives.
    fn value(self) -> f64;
}

impl Scalar for f64 {
    fn value(self) -> f64 {
        self
    }
}

/// A value and its partial derivatives with respect to N unknowns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// ∂value/∂unknown_k.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// The k-th unknown itself, with value `v`.
    pub fn variable(v: f64, k: usize) -> Self {
        let mut d = [0.0; N];
        d[k] = 1.0;
        Dual { v, d }
    }
}

impl<const N: usize> From<f64> for Dual<N> {
    fn from(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }
}

impl<const N: usize> Scalar for Dual<N> {
    fn value(self) -> f64 {
        self.v
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for k in 0..N {
            self.d[k] += o.d[k];
        }
        self
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for k in 0..N {
            self.d[k] -= o.d[k];
        }
        self
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for (k, dk) in d.iter_mut().enumerate() {
            *dk = self.d[k] * o.v + self.v * o.d[k];
        }
        Dual { v: self.v * o.v, d }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        let mut d = [0.0; N];
        for (k, dk) in d.iter_mut().enumerate() {
            *dk = (self.d[k] - v * o.d[k]) * inv;
        }
        Dual { v, d }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    fn neg(mut self) -> Self {
        self.v = -self.v;
        for k in 0..N {
            self.d[k] = -self.d[k];
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_of_a_rational_function_match_finite_differences() {
        let f = |x: Dual<2>, y: Dual<2>| (x * x * y - Dual::from(3.0)) / (y + x * Dual::from(0.5));
        let fx = |x: f64, y: f64| (x * x * y - 3.0) / (y + x * 0.5);
        let (x0, y0) = (1.3, -2.7);
        let r = f(Dual::variable(x0, 0), Dual::variable(y0, 1));
        let h = 1e-6;
        let dx = (fx(x0 + h, y0) - fx(x0 - h, y0)) / (2.0 * h);
        let dy = (fx(x0, y0 + h) - fx(x0, y0 - h)) / (2.0 * h);
        assert!((r.v - fx(x0, y0)).abs() < 1e-14);
        assert!((r.d[0] - dx).abs() < 1e-7, "{} vs {}", r.d[0], dx);
        assert!((r.d[1] - dy).abs() < 1e-7, "{} vs {}", r.d[1], dy);
    }
}
