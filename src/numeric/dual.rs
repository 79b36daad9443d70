//! Forward-mode dual numbers: a value with its gradient with respect to `N` inputs, carried
//! through each operation by the chain rule. The learner's residual (the signed radial distance
//! of a tapered superquadric, about ten logarithms and exponentials in the log domain) is
//! differentiated this way in one pass: the transcendental calls are made once and each adds
//! `N` multiplications, where forward differences would repeat the whole evaluation per
//! parameter.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A value and its partial derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const N: usize> {
    pub v: f64,
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A constant (no derivative).
    #[inline]
    pub fn constant(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }

    /// Input number `k`: derivative 1 with respect to itself.
    #[inline]
    pub fn variable(v: f64, k: usize) -> Self {
        let mut d = [0.0; N];
        d[k] = 1.0;
        Dual { v, d }
    }

    /// `f(self)` given `f(v)` and `f'(v)`.
    #[inline]
    fn chain(self, v: f64, slope: f64) -> Self {
        Dual {
            v,
            d: self.d.map(|x| x * slope),
        }
    }

    #[inline]
    pub fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }

    /// `ln |self|`: the derivative of `ln |u|` is `u'/u` on either side of zero. At zero the value
    /// is `-inf` with no derivative, which [`Dual::log_sum_exp`] takes as an absent term.
    #[inline]
    pub fn ln_abs(self) -> Self {
        if self.v == 0.0 {
            return Dual::constant(f64::NEG_INFINITY);
        }
        self.chain(self.v.abs().ln(), 1.0 / self.v)
    }

    #[inline]
    pub fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s)
    }

    #[inline]
    pub fn abs(self) -> Self {
        if self.v < 0.0 { -self } else { self }
    }

    /// The larger of the two by value (the derivative of the one taken).
    #[inline]
    pub fn max(self, other: Self) -> Self {
        if self.v >= other.v { self } else { other }
    }

    /// `ln(e^a + e^b)`, exact when either is `-inf` (an absent term).
    #[inline]
    pub fn log_sum_exp(a: Self, b: Self) -> Self {
        let (hi, lo) = if a.v >= b.v { (a, b) } else { (b, a) };
        if lo.v == f64::NEG_INFINITY {
            return hi;
        }
        // ln(e^hi (1 + e^(lo-hi))): the weight of `lo` is w = e^(lo-hi) / (1 + e^(lo-hi)).
        let e = (lo.v - hi.v).exp();
        let w = e / (1.0 + e);
        Dual {
            v: hi.v + e.ln_1p(),
            d: std::array::from_fn(|k| (1.0 - w) * hi.d[k] + w * lo.d[k]),
        }
    }

    /// `c * self` for a log-domain value: `-inf` stays an absent term whatever `c` is.
    #[inline]
    pub fn scale_log(self, c: Self) -> Self {
        if self.v == f64::NEG_INFINITY { self } else { c * self }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        let mut d = self.d;
        for (a, b) in d.iter_mut().zip(o.d) {
            *a += b;
        }
        Dual { v: self.v + o.v, d }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        let mut d = self.d;
        for (a, b) in d.iter_mut().zip(o.d) {
            *a -= b;
        }
        Dual { v: self.v - o.v, d }
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    // The product rule.
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            d: std::array::from_fn(|k| self.d[k] * o.v + self.v * o.d[k]),
        }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        Dual {
            v,
            d: std::array::from_fn(|k| (self.d[k] - v * o.d[k]) * inv),
        }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Dual {
            v: -self.v,
            d: self.d.map(|x| -x),
        }
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(self, c: f64) -> Self {
        Dual {
            v: self.v + c,
            d: self.d,
        }
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, c: f64) -> Self {
        self.chain(self.v * c, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences of a two-argument function.
    fn numeric(f: impl Fn(f64, f64) -> f64, x: f64, y: f64) -> [f64; 2] {
        let h = 1e-6;
        [
            (f(x + h, y) - f(x - h, y)) / (2.0 * h),
            (f(x, y + h) - f(x, y - h)) / (2.0 * h),
        ]
    }

    #[test]
    fn the_operations_match_central_differences() {
        type D = Dual<2>;
        type Case = (Box<dyn Fn(D, D) -> D>, Box<dyn Fn(f64, f64) -> f64>);
        let cases: Vec<Case> = vec![
            (Box::new(|x, y| x * y + x), Box::new(|x, y| x * y + x)),
            (Box::new(|x, y| x / y - y), Box::new(|x, y| x / y - y)),
            (Box::new(|x, y| (x * y).exp()), Box::new(|x, y| (x * y).exp())),
            (Box::new(|x, y| (x - y).ln_abs()), Box::new(|x, y| (x - y).abs().ln())),
            (
                Box::new(|x, y| (x * x + y * y).sqrt()),
                Box::new(|x, y| (x * x + y * y).sqrt()),
            ),
            (
                Box::new(|x, y| D::log_sum_exp(x * 3.0, y.ln_abs())),
                Box::new(|x, y| ((3.0 * x).exp() + y.abs()).ln()),
            ),
            (
                Box::new(|x, y| (x - y).abs().max(y * 0.5)),
                Box::new(|x, y| (x - y).abs().max(y * 0.5)),
            ),
        ];
        for (i, (fd, ff)) in cases.iter().enumerate() {
            for (x, y) in [(0.3, 1.7), (-0.8, 0.4), (1.1, -2.5)] {
                let got = fd(D::variable(x, 0), D::variable(y, 1));
                assert!((got.v - ff(x, y)).abs() < 1e-12, "case {i} value");
                let want = numeric(ff, x, y);
                for (k, (got, want)) in got.d.iter().zip(want).enumerate() {
                    let tol = 1e-6 * (1.0 + want.abs());
                    assert!((got - want).abs() < tol, "case {i} at ({x}, {y}): d{k} {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn an_absent_log_term_carries_no_derivative() {
        let zero = Dual::<1>::variable(0.0, 0).ln_abs();
        assert_eq!(zero.v, f64::NEG_INFINITY);
        let s = zero.scale_log(Dual::variable(2.0, 0));
        let l = Dual::log_sum_exp(s, Dual::variable(0.5, 0));
        assert_eq!(l.v, 0.5);
        assert_eq!(l.d, [1.0]);
    }
}
