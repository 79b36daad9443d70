//! A few `f64` values processed together, written so the compiler turns each operation into
//! vector instructions, and the logarithm and exponential for them.
//!
//! The detector's pose fits, consensus counts and scores evaluate one residual for each of
//! hundreds of thousands of points. One at a time, each is a chain of branches and two libm
//! calls; four at a time in [`Lanes`], the same arithmetic is straight-line code that the
//! compiler vectorizes. [`Lanes<1>`] is the scalar case of the same code, so a residual taken
//! alone and one taken in a group of four are the same to the last bit: the rounding of each
//! operation is the IEEE one, whatever the vector width, and nothing is fused.
//!
//! [`Lanes::ln`] and [`Lanes::exp`] are branch-free and accurate to a few units in the last place
//! (the tests hold them to libm's within 4e-16 relative) for the arguments the residuals take:
//! positive normal numbers for the logarithm, and for the exponential anything (below -708 it
//! gives a value below 1e-307 rather than 0; above 709, infinity).

// Lane loops index several arrays in step; iterators over zips of them say it less plainly.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, Div, Mul, Neg, Sub};

/// `L` values, each operated on alone.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(transparent)]
pub struct Lanes<const L: usize>(pub [f64; L]);

/// `L` booleans, the outcome of a comparison of [`Lanes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mask<const L: usize>(pub [bool; L]);

macro_rules! lanewise {
    ($trait:ident, $f:ident, $op:tt) => {
        impl<const L: usize> $trait for Lanes<L> {
            type Output = Lanes<L>;
            #[inline(always)]
            fn $f(self, o: Lanes<L>) -> Lanes<L> {
                let mut r = self.0;
                for i in 0..L {
                    r[i] = self.0[i] $op o.0[i];
                }
                Lanes(r)
            }
        }
        impl<const L: usize> $trait<f64> for Lanes<L> {
            type Output = Lanes<L>;
            #[inline(always)]
            fn $f(self, o: f64) -> Lanes<L> {
                let mut r = self.0;
                for i in 0..L {
                    r[i] = self.0[i] $op o;
                }
                Lanes(r)
            }
        }
    };
}

lanewise!(Add, add, +);
lanewise!(Sub, sub, -);
lanewise!(Mul, mul, *);
lanewise!(Div, div, /);

impl<const L: usize> Neg for Lanes<L> {
    type Output = Lanes<L>;
    #[inline(always)]
    fn neg(self) -> Lanes<L> {
        self.map(|x| -x)
    }
}

impl<const L: usize> Lanes<L> {
    #[inline(always)]
    pub fn splat(x: f64) -> Lanes<L> {
        Lanes([x; L])
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(f64) -> f64) -> Lanes<L> {
        let mut r = self.0;
        for x in r.iter_mut() {
            *x = f(*x);
        }
        Lanes(r)
    }

    #[inline(always)]
    fn zip(self, o: Lanes<L>, f: impl Fn(f64, f64) -> f64) -> Lanes<L> {
        let mut r = self.0;
        for i in 0..L {
            r[i] = f(self.0[i], o.0[i]);
        }
        Lanes(r)
    }

    #[inline(always)]
    fn bits(self, f: impl Fn(u64) -> u64) -> Lanes<L> {
        self.map(|x| f64::from_bits(f(x.to_bits())))
    }

    #[inline(always)]
    pub fn abs(self) -> Lanes<L> {
        self.bits(|b| b & !SIGN)
    }

    /// `self`'s magnitude with `sign`'s sign.
    #[inline(always)]
    pub fn copysign(self, sign: Lanes<L>) -> Lanes<L> {
        self.zip(sign, |m, s| {
            f64::from_bits((m.to_bits() & !SIGN) | (s.to_bits() & SIGN))
        })
    }

    #[inline(always)]
    pub fn sqrt(self) -> Lanes<L> {
        self.map(f64::sqrt)
    }

    /// The lane-wise maximum (`o` where either is NaN: the form that compiles to one
    /// instruction).
    #[inline(always)]
    pub fn max(self, o: Lanes<L>) -> Lanes<L> {
        self.zip(o, |a, b| if a > b { a } else { b })
    }

    #[inline(always)]
    pub fn min(self, o: Lanes<L>) -> Lanes<L> {
        self.zip(o, |a, b| if a < b { a } else { b })
    }

    #[inline(always)]
    pub fn lt(self, o: Lanes<L>) -> Mask<L> {
        let mut m = [false; L];
        for i in 0..L {
            m[i] = self.0[i] < o.0[i];
        }
        Mask(m)
    }

    #[inline(always)]
    pub fn le(self, o: Lanes<L>) -> Mask<L> {
        let mut m = [false; L];
        for i in 0..L {
            m[i] = self.0[i] <= o.0[i];
        }
        Mask(m)
    }

    #[inline(always)]
    pub fn eq(self, o: Lanes<L>) -> Mask<L> {
        let mut m = [false; L];
        for i in 0..L {
            m[i] = self.0[i] == o.0[i];
        }
        Mask(m)
    }

    /// The sum of the lanes, in order.
    #[inline(always)]
    pub fn sum(self) -> f64 {
        self.0.iter().sum()
    }

    /// The natural logarithm of positive normal numbers (and `+inf` for `+inf`). Zero and
    /// subnormal arguments give about -709 instead of `-inf` or their logarithm: callers that
    /// can meet them select their own value there.
    #[inline(always)]
    pub fn ln(self) -> Lanes<L> {
        // x = 2^k z with z in [sqrt(1/2), sqrt(2)): shifting the bits by those of sqrt(1/2)
        // below 1 carries into the exponent exactly where z would leave that range. The
        // exponent is unbiased through a float (there is no vector int64-to-double conversion
        // below AVX-512): 2^52 + k as the bits of a double, minus 2^52.
        let mut k = self.0;
        let mut z = self.0;
        for i in 0..L {
            let b = self.0[i].to_bits();
            let kb = b.wrapping_add(ONE_BITS - SQRT_HALF_BITS) >> 52;
            z[i] = f64::from_bits(b.wrapping_sub(kb.wrapping_sub(1023) << 52));
            k[i] = f64::from_bits(TWO52_BITS | kb) - (TWO52 + 1023.0);
        }
        let (k, z) = (Lanes(k), Lanes(z));
        // ln z = 2 atanh(s) = 2 s (1 + s^2/3 + s^4/5 + ...), s = (z - 1) / (z + 1), |s| < 0.172.
        let f = z - 1.0;
        let s = f / (f + 2.0);
        let w = s * s;
        let mut p = Lanes::splat(LN_SERIES[LN_SERIES.len() - 1]);
        for &c in LN_SERIES[..LN_SERIES.len() - 1].iter().rev() {
            p = p * w + c;
        }
        // 2s = f - f s: the larger part exact, the rest small.
        let r = k * LN2_LO + (s * w * p * 2.0 - f * s) + f + k * LN2_HI;
        // +inf and NaN stay themselves; anything else the bits above give is a finite logarithm.
        let mut out = r.0;
        for i in 0..L {
            if !(self.0[i] < f64::INFINITY) {
                out[i] = self.0[i];
            }
        }
        Lanes(out)
    }

    /// `e^x`, for any `x` (`NaN` stays `NaN`).
    #[inline(always)]
    pub fn exp(self) -> Lanes<L> {
        let x = self.max(Lanes::splat(-708.0)).min(Lanes::splat(709.0));
        // x = k ln 2 + r, |r| <= ln 2 / 2; k rounded by adding 1.5 * 2^52, which leaves it in
        // the low bits.
        let t = x * std::f64::consts::LOG2_E + ROUND;
        let k = t - ROUND;
        let r = x - k * LN2_HI - k * LN2_LO;
        let mut p = Lanes::splat(EXP_SERIES[EXP_SERIES.len() - 1]);
        for &c in EXP_SERIES[..EXP_SERIES.len() - 1].iter().rev() {
            p = p * r + c;
        }
        // 2^k from its bits: k lies in [-1021, 1023], within the exponent field.
        let mut out = p.0;
        for i in 0..L {
            let kb = t.0[i].to_bits().wrapping_sub(ROUND.to_bits());
            out[i] = p.0[i] * f64::from_bits(kb.wrapping_add(1023) << 52);
            if self.0[i] > 709.0 {
                out[i] = f64::INFINITY;
            }
            if self.0[i].is_nan() {
                out[i] = self.0[i];
            }
        }
        Lanes(out)
    }

    /// `x^y` for `x >= 0`: `e^(y ln x)`, and 0 at `x = 0` (for `y > 0`).
    #[inline(always)]
    pub fn powf_pos(self, y: f64) -> Lanes<L> {
        let v = (self.ln() * y).exp();
        Mask::select(self.eq(Lanes::splat(0.0)), Lanes::splat(0.0), v)
    }
}

impl<const L: usize> Mask<L> {
    /// `a` where the mask is set, else `b`.
    #[inline(always)]
    pub fn select(m: Mask<L>, a: Lanes<L>, b: Lanes<L>) -> Lanes<L> {
        let mut r = b.0;
        for i in 0..L {
            if m.0[i] {
                r[i] = a.0[i];
            }
        }
        Lanes(r)
    }

    #[inline(always)]
    pub fn any(self) -> bool {
        self.0.iter().any(|&b| b)
    }

    #[inline(always)]
    pub fn or(self, o: Mask<L>) -> Mask<L> {
        let mut r = self.0;
        for i in 0..L {
            r[i] |= o.0[i];
        }
        Mask(r)
    }
}

/// A function compiled twice, for the widest vectors the CPU has: with AVX2 four lanes of
/// [`Lanes`] are one instruction, with the SSE2 every x86-64 has they are two. Which one runs is
/// decided at run time; the results are the same to the bit (nothing is fused, and IEEE rounding
/// does not depend on the width).
macro_rules! widened {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident : $ty:ty),* $(,)?) -> $ret:ty $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            #[inline(always)]
            fn body($($arg: $ty),*) -> $ret $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2($($arg: $ty),*) -> $ret {
                body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") && !$crate::numeric::lanes::baseline_only() {
                // SAFETY: the CPU has AVX2.
                return unsafe { avx2($($arg),*) };
            }
            body($($arg),*)
        }
    };
}
pub(crate) use widened;

/// Tests set this to run the baseline code where the CPU has AVX2, to hold the two to the same
/// results.
#[cfg(test)]
pub(crate) static BASELINE_ONLY: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[cfg(test)]
#[inline(always)]
pub(crate) fn baseline_only() -> bool {
    BASELINE_ONLY.load(std::sync::atomic::Ordering::Relaxed)
}

#[cfg(not(test))]
#[inline(always)]
pub(crate) fn baseline_only() -> bool {
    false
}

const SIGN: u64 = 1 << 63;
const ONE_BITS: u64 = 0x3ff0_0000_0000_0000;
/// The bits of `sqrt(1/2)`, rounded down.
const SQRT_HALF_BITS: u64 = 0x3fe6_a09e_667f_3bcd;
const TWO52: f64 = 4_503_599_627_370_496.0;
const TWO52_BITS: u64 = 0x4330_0000_0000_0000;
/// 1.5 * 2^52: adding it rounds to an integer, kept in the low bits of the sum.
const ROUND: f64 = 6_755_399_441_055_744.0;
/// `ln 2` in two parts: the first with its low bits zero, so `k * LN2_HI` is exact for the
/// exponents of doubles.
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
/// `1/3, 1/5, ...`: `atanh(s)/s - 1 = s^2 (1/3 + s^2/5 + ...)`; |s| < 0.172 makes the 10th term
/// below 1e-17 relative.
const LN_SERIES: [f64; 9] = [
    1.0 / 3.0,
    1.0 / 5.0,
    1.0 / 7.0,
    1.0 / 9.0,
    1.0 / 11.0,
    1.0 / 13.0,
    1.0 / 15.0,
    1.0 / 17.0,
    1.0 / 19.0,
];
/// `1/n!` for `n = 0..=13`: the Taylor series of `e^r` for |r| <= 0.347, whose 14th term is below
/// 5e-18.
const EXP_SERIES: [f64; 14] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn rel(a: f64, b: f64) -> f64 {
        if a == b { 0.0 } else { ((a - b) / b).abs() }
    }

    #[test]
    fn ln_agrees_with_libm() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut worst: f64 = 0.0;
        let mut check = |x: f64| {
            let got = Lanes::<1>([x]).ln().0[0];
            let want = x.ln();
            // Near 1 the logarithm is small: compare against its absolute size there.
            let err = if (x - 1.0).abs() < 0.1 {
                (got - want).abs() / (x - 1.0).abs().max(1e-300)
            } else {
                rel(got, want)
            };
            assert!(err < 4e-16, "ln({x:e}) = {got:e}, libm {want:e}");
            worst = worst.max(err);
        };
        for _ in 0..200_000 {
            check(10f64.powf(rng.random_range(-300.0..300.0)));
            check(rng.random_range(0.5..2.0));
        }
        for x in [
            1.0,
            2.0,
            0.5,
            std::f64::consts::SQRT_2,
            0.7071067811865475,
            3e-308,
            1.7e308,
        ] {
            check(x);
        }
        assert_eq!(Lanes::<1>([1.0]).ln().0[0], 0.0);
        assert_eq!(Lanes::<1>([f64::INFINITY]).ln().0[0], f64::INFINITY);
        assert!(Lanes::<1>([0.0]).ln().0[0] < -700.0);
    }

    #[test]
    fn exp_agrees_with_libm() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(2);
        for _ in 0..200_000 {
            let x: f64 = rng.random_range(-700.0..700.0);
            let got = Lanes::<1>([x]).exp().0[0];
            assert!(rel(got, x.exp()) < 4e-16, "exp({x}) = {got:e}, libm {:e}", x.exp());
            let x: f64 = rng.random_range(-1.0..1.0);
            let got = Lanes::<1>([x]).exp().0[0];
            assert!(rel(got, x.exp()) < 4e-16, "exp({x}) = {got:e}, libm {:e}", x.exp());
        }
        for x in [0.0, 1.0, -1.0, 708.9, -707.9] {
            let got = Lanes::<1>([x]).exp().0[0];
            assert!(rel(got, x.exp()) < 4e-16, "exp({x}) = {got:e}");
        }
        assert_eq!(Lanes::<1>([0.0]).exp().0[0], 1.0);
        assert_eq!(Lanes::<1>([800.0]).exp().0[0], f64::INFINITY);
        assert!(Lanes::<1>([-800.0]).exp().0[0] < 1e-307);
        assert!(Lanes::<1>([f64::NAN]).exp().0[0].is_nan());
    }

    #[test]
    fn four_lanes_are_four_single_lanes_to_the_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for _ in 0..10_000 {
            let x = Lanes::<4>(std::array::from_fn(|_| 10f64.powf(rng.random_range(-20.0..20.0))));
            let y: f64 = rng.random_range(0.05..3.0);
            let four = x.powf_pos(y);
            for i in 0..4 {
                assert_eq!(four.0[i].to_bits(), Lanes::<1>([x.0[i]]).powf_pos(y).0[0].to_bits());
            }
        }
    }

    #[test]
    fn powf_pos_is_zero_at_zero_and_agrees_elsewhere() {
        let v = Lanes::<4>([0.0, 1.0, 2.0, 1e-3]).powf_pos(0.4);
        assert_eq!(v.0[0], 0.0);
        for (i, x) in [1.0f64, 2.0, 1e-3].iter().enumerate() {
            assert!(rel(v.0[i + 1], x.powf(0.4)) < 1e-15);
        }
    }
}
