//! Small integer powers, unrolled: the superquadric's exponents are whole numbers for the
//! shapes of everyday objects (boxes and cylinders of e = 0.1, 1 and 2).

/// `x^n` for the small integer powers of the plain form, unrolled: `powi` is a call into a
/// generic loop (compiler-builtins' `__powidf2`), which cost as much as the rest of a residual.
#[inline(always)]
pub(crate) fn ipow(x: f64, n: i32) -> f64 {
    match n {
        0 => 1.0,
        1 => x,
        2 => x * x,
        3 => x * x * x,
        4 => {
            let x2 = x * x;
            x2 * x2
        }
        5 => {
            let x2 = x * x;
            x2 * x2 * x
        }
        6 => {
            let x3 = x * x * x;
            x3 * x3
        }
        8 => {
            let x2 = x * x;
            let x4 = x2 * x2;
            x4 * x4
        }
        10 => {
            let x2 = x * x;
            let x4 = x2 * x2;
            x4 * x4 * x2
        }
        20 => {
            let x2 = x * x;
            let x4 = x2 * x2;
            let x10 = x4 * x4 * x2;
            x10 * x10
        }
        _ => x.powi(n),
    }
}

/// An exponent that is an integer (to rounding), as a power for [`ipow`].
#[inline]
pub(crate) fn int_exponent(v: f64) -> Option<i32> {
    // Rounds by truncation of v + 0.5 (v is checked to lie in [0, 64]): `f64::round` is a libm
    // call on baseline x86-64.
    if !(-0.5..=64.5).contains(&v) {
        return None;
    }
    let r = (v + 0.5) as i32;
    ((v - r as f64).abs() < 1e-9 && r >= 0).then_some(r)
}
