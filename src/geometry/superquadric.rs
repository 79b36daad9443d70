//! The tapered superellipsoid of Barr, in its own (local) frame.
//!
//! Paper eq. (1):
//! `F = ((x/a1)^(2/e2) + (y/a2)^(2/e2))^(e2/e1) + (z/a3)^(2/e1)`, evaluated after undoing the
//! linear taper along z (Solina & Bajcsy 1990):
//! `X = (kx z/a3 + 1) x`, `Y = (ky z/a3 + 1) y`, `Z = z`.
//!
//! Everything here is evaluated in the log domain. With `e1 = 0.1` the exponents reach 20, so a
//! point ten sizes away gives `(10)^20` in the plain form and the sums lose every digit near the
//! coordinate planes; the log form `ln F = logsumexp((e2/e1) logsumexp(lu, lv), lb)` stays finite
//! and accurate everywhere (it is the `max * (1 + (min/max)^(1/t))^t` power sum of METHOD_NOTES
//! written with logarithms), and `ln 0 = -inf` handles points on the coordinate planes exactly.

use super::powers::{int_exponent, ipow};
use nalgebra::{Isometry3, Point3, Vector3};
use std::fmt;

/// Bounds of the shape exponents: below 0.1 the surface is numerically a box and the residual's
/// derivatives explode; above 2 the shape is no longer convex.
pub const EPSILON_MIN: f64 = 0.1;
pub const EPSILON_MAX: f64 = 2.0;
/// Taper coefficients must keep the cross-section factor `k z/a3 + 1` positive on `|z| <= a3`.
pub const TAPER_MAX: f64 = 0.99;

/// Why a set of superquadric parameters was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    #[error("{name} = {value} must be a finite size > 0 m")]
    Size { name: &'static str, value: f64 },
    #[error("{name} = {value} must lie in [{EPSILON_MIN}, {EPSILON_MAX}]")]
    Exponent { name: &'static str, value: f64 },
    #[error("{name} = {value} must lie in (-1, 1) (at most {TAPER_MAX} in magnitude)")]
    Taper { name: &'static str, value: f64 },
}

/// A tapered superellipsoid's size, shape and taper (no pose).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Superquadric {
    /// Half-sizes along the local x, y, z axes (m).
    pub a: [f64; 3],
    /// Shape exponent in the z (north-south) direction.
    pub e1: f64,
    /// Shape exponent in the x-y (east-west) direction.
    pub e2: f64,
    /// Linear taper of x along z.
    pub kx: f64,
    /// Linear taper of y along z.
    pub ky: f64,
}

impl fmt::Display for Superquadric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a = ({:.4}, {:.4}, {:.4}) m, e1 = {}, e2 = {}, kx = {}, ky = {}",
            self.a[0], self.a[1], self.a[2], self.e1, self.e2, self.kx, self.ky
        )
    }
}

/// The value and the gradient (with respect to the local point) of the residual `F^e1 - 1`.
#[derive(Debug, Clone, Copy)]
pub struct ResidualGrad {
    pub residual: f64,
    pub grad: Vector3<f64>,
}

/// `ln(e^a + e^b)` that is exact for `-inf` arguments.
#[inline]
pub(crate) fn logsumexp(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    if hi == f64::NEG_INFINITY {
        return f64::NEG_INFINITY;
    }
    hi + (lo - hi).exp().ln_1p()
}

impl Superquadric {
    /// A validated superquadric.
    pub fn new(a: [f64; 3], e1: f64, e2: f64, kx: f64, ky: f64) -> Result<Self, ShapeError> {
        for (name, value) in [("a1", a[0]), ("a2", a[1]), ("a3", a[2])] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ShapeError::Size { name, value });
            }
        }
        for (name, value) in [("e1", e1), ("e2", e2)] {
            if !(EPSILON_MIN..=EPSILON_MAX).contains(&value) {
                return Err(ShapeError::Exponent { name, value });
            }
        }
        for (name, value) in [("kx", kx), ("ky", ky)] {
            if !(value.is_finite() && value.abs() <= TAPER_MAX) {
                return Err(ShapeError::Taper { name, value });
            }
        }
        Ok(Self { a, e1, e2, kx, ky })
    }

    /// An untapered superquadric.
    pub fn untapered(a: [f64; 3], e1: f64, e2: f64) -> Result<Self, ShapeError> {
        Self::new(a, e1, e2, 0.0, 0.0)
    }

    /// True when rotation about the local z axis leaves the shape unchanged (a body of
    /// revolution: equal x and y sizes, round cross-section, no differential taper). Its pose then
    /// has only 5 observable degrees of freedom.
    pub fn is_revolution(&self) -> bool {
        (self.a[0] - self.a[1]).abs() <= 1e-9 * self.a[0].max(self.a[1])
            && (self.e2 - 1.0).abs() < 1e-9
            && (self.kx - self.ky).abs() < 1e-12
    }

    /// True when the taper breaks the `z -> -z` symmetry, so the sign of the z axis is observable.
    pub fn is_tapered(&self) -> bool {
        self.kx != 0.0 || self.ky != 0.0
    }

    pub fn max_size(&self) -> f64 {
        self.a[0].max(self.a[1]).max(self.a[2])
    }

    pub fn min_size(&self) -> f64 {
        self.a[0].min(self.a[1]).min(self.a[2])
    }

    /// Half-extents of the local axis-aligned box that contains the tapered shape.
    pub fn local_half_extents(&self) -> Vector3<f64> {
        Vector3::new(
            self.a[0] * (1.0 + self.kx.abs()),
            self.a[1] * (1.0 + self.ky.abs()),
            self.a[2],
        )
    }

    /// Radius of a sphere about the local origin that contains the shape.
    pub fn bounding_radius(&self) -> f64 {
        self.local_half_extents().norm()
    }

    /// Cross-section scale factors `(kx z/a3 + 1, ky z/a3 + 1)` at height `z`.
    ///
    /// Beyond `|z| > a3` the linear taper can reach zero or flip sign, which would fold space; the
    /// factors are clamped to a small positive value there. Such points have `|z/a3| > 1` and are
    /// outside whatever the clamp does, so the clamp only keeps the function finite and monotone.
    #[inline]
    fn taper_factors(&self, z: f64) -> (f64, f64) {
        let t = z / self.a[2];
        let fx = (self.kx * t + 1.0).max(0.5 * (1.0 - self.kx.abs()));
        let fy = (self.ky * t + 1.0).max(0.5 * (1.0 - self.ky.abs()));
        (fx, fy)
    }

    /// Apply the taper to an untapered local point.
    #[inline]
    pub fn taper(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let (fx, fy) = self.taper_factors(p.z);
        Vector3::new(p.x * fx, p.y * fy, p.z)
    }

    /// The superellipse radius of a cross-section point `(x, y)` (untapered, local): 1 on the
    /// section's outline, below 1 inside it. Along the axis it is the radius of the side wall
    /// extended past the ends, as `untaper` gives the point's section.
    #[inline]
    pub fn section_radius(&self, x: f64, y: f64) -> f64 {
        let e = 2.0 / self.e2;
        ((x.abs() / self.a[0]).powf(e) + (y.abs() / self.a[1]).powf(e)).powf(self.e2 / 2.0)
    }

    /// Undo the taper of a local point.
    #[inline]
    pub fn untaper(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let (fx, fy) = self.taper_factors(p.z);
        Vector3::new(p.x / fx, p.y / fy, p.z)
    }

    /// `ln F` of an *untapered* local point, with the intermediate logs the gradient needs.
    #[inline]
    fn ln_f_parts(&self, q: &Vector3<f64>) -> LnParts {
        let lx = (q.x.abs() / self.a[0]).ln();
        let ly = (q.y.abs() / self.a[1]).ln();
        let lz = (q.z.abs() / self.a[2]).ln();
        let lu = (2.0 / self.e2) * lx;
        let lv = (2.0 / self.e2) * ly;
        let ls = logsumexp(lu, lv);
        let la = (self.e2 / self.e1) * ls;
        let lb = (2.0 / self.e1) * lz;
        let lf = logsumexp(la, lb);
        LnParts { lu, lv, ls, la, lb, lf }
    }

    /// The plain (not log-domain) evaluation of eq. (1) of an untapered point, when every
    /// exponent `2/e1`, `2/e2` is an integer (the shapes people write: e = 0.1, 0.2, 0.4, 0.5,
    /// 1, 2) and the point is within 1e4 sizes, where integer powers cannot overflow. It needs
    /// at most two transcendental calls instead of about ten, and the detector spends most of
    /// its time here.
    #[inline]
    fn plain(&self, q: &Vector3<f64>) -> Option<f64> {
        let n1 = int_exponent(2.0 / self.e1)?;
        let n2 = int_exponent(2.0 / self.e2)?;
        let (rx, ry, rz) = (q.x.abs() / self.a[0], q.y.abs() / self.a[1], q.z.abs() / self.a[2]);
        if rx > 1e4 || ry > 1e4 || rz > 1e4 {
            return None;
        }
        let s = ipow(rx, n2) + ipow(ry, n2);
        let m = self.e2 / self.e1;
        // e2/e1 is often a whole or a half number (1/0.4 = 2.5): s^(k/2) = s^(k div 2) sqrt(s)
        // costs a fraction of a general power.
        let a = match int_exponent(2.0 * m) {
            Some(k) if k % 2 == 0 => ipow(s, k / 2),
            Some(k) => ipow(s, k / 2) * s.sqrt(),
            None => s.powf(m),
        };
        Some(a + ipow(rz, n1))
    }

    /// `F^e1` from `F`.
    #[inline]
    fn pow_e1(&self, f: f64) -> f64 {
        if self.e1 == 1.0 {
            f
        } else if self.e1 == 0.5 {
            f.sqrt()
        } else if f > 0.0 {
            // exp(e1 ln F) is two of libm's fast paths, where `powf` takes its general one (the
            // detector evaluates this hundreds of thousands of times a query); the two differ by
            // a few units in the last place.
            (self.e1 * f.ln()).exp()
        } else {
            f.powf(self.e1)
        }
    }

    /// The inside-outside function F (paper eq. 1) of a local point: < 1 inside, 1 on the
    /// surface, > 1 outside. May be `+inf` only for points absurdly far away (beyond 1e15 sizes).
    pub fn inside_outside(&self, p: &Vector3<f64>) -> f64 {
        let q = self.untaper(p);
        match self.plain(&q) {
            Some(f) => f,
            None => self.ln_f_parts(&q).lf.exp(),
        }
    }

    /// `F^e1`, the quantity of eq. (2) and (3): its deviation from 1 grows roughly linearly with
    /// the distance from the surface whatever the shape exponents, which is why the paper uses it.
    #[inline]
    pub fn f_pow_e1(&self, p: &Vector3<f64>) -> f64 {
        let q = self.untaper(p);
        match self.plain(&q) {
            Some(f) => self.pow_e1(f),
            None => (self.e1 * self.ln_f_parts(&q).lf).exp(),
        }
    }

    /// The algebraic residual `F^e1 - 1` (paper eq. 2) of a local point.
    #[inline]
    pub fn residual(&self, p: &Vector3<f64>) -> f64 {
        self.f_pow_e1(p) - 1.0
    }

    /// The product of the half-sizes a1·a2·a3 (an eighth of the volume of the box the untapered
    /// shape fits in): the scale by which the detector orders the parts of a model (the largest
    /// anchors the search, the smallest sets the rigid refinement's bands). It is not the
    /// superquadric's volume, which also depends on the exponents.
    pub fn box_volume(&self) -> f64 {
        self.a[0] * self.a[1] * self.a[2]
    }

    /// The residual of an *untapered* local point in the log domain.
    pub(crate) fn residual_log(&self, q: &Vector3<f64>) -> f64 {
        (self.e1 * self.ln_f_parts(q).lf).exp() - 1.0
    }

    /// `F^e1` evaluated in the log domain only (the reference the fast path is tested against).
    #[cfg(test)]
    pub(crate) fn f_pow_e1_log(&self, p: &Vector3<f64>) -> f64 {
        (self.e1 * self.ln_f_parts(&self.untaper(p)).lf).exp()
    }

    /// `F^e1` and its gradient in the untapered frame, log domain; `None` at the centre or for an
    /// absurdly far point (gradient undefined or not finite).
    pub(crate) fn log_grad_untapered(&self, q: &Vector3<f64>) -> Option<(f64, f64, f64, f64)> {
        let l = self.ln_f_parts(q);
        let g = (self.e1 * l.lf).exp();
        if g == 0.0 || !g.is_finite() {
            // The centre (gradient undefined, any direction is as good) or an absurdly far point.
            return None;
        }
        // d(ln F) = wA d(lA) + wB d(lB) with wA = A/F, wB = B/F; d(lA) = (e2/e1) (wu dlu + wv dlv);
        // dlu/dx = (2/e2)/x. So dG/dx = G e1 dlnF/dx = 2 G wA wu / x, and likewise for y; z gives
        // 2 G wB / z. A zero coordinate contributes nothing (the limit for e <= 2).
        let wa = (l.la - l.lf).exp();
        let wb = (l.lb - l.lf).exp();
        let (wu, wv) = if l.ls == f64::NEG_INFINITY {
            (0.0, 0.0)
        } else {
            ((l.lu - l.ls).exp(), (l.lv - l.ls).exp())
        };
        let gx = if q.x != 0.0 { 2.0 * g * wa * wu / q.x } else { 0.0 };
        let gy = if q.y != 0.0 { 2.0 * g * wa * wv / q.y } else { 0.0 };
        let gz = if q.z != 0.0 { 2.0 * g * wb / q.z } else { 0.0 };
        Some((g, gx, gy, gz))
    }

    /// The point where the ray from the centre through `p` (taken in the untapered frame) meets
    /// the surface, mapped back through the taper. `None` for the centre itself.
    pub fn radial_surface_point(&self, p: &Vector3<f64>) -> Option<Vector3<f64>> {
        let q = self.untaper(p);
        let lf = self.ln_f_parts(&q).lf;
        if lf == f64::NEG_INFINITY || !lf.is_finite() {
            return None;
        }
        // F is homogeneous of degree 2/e1 in the untapered point: F(s q) = s^(2/e1) F(q).
        let s = (-0.5 * self.e1 * lf).exp();
        Some(self.taper(&(q * s)))
    }

    /// Radial Euclidean distance: the distance from `p` to the surface point on the ray from the
    /// centre through `p`. Exact along that ray for an untapered shape and close to the true
    /// distance near the surface; the ray is taken in the untapered frame for a tapered one.
    pub fn radial_distance(&self, p: &Vector3<f64>) -> f64 {
        match self.radial_surface_point(p) {
            Some(s) => (p - s).norm(),
            None => self.min_size(),
        }
    }

    /// [`Self::radial_distance`], negative inside: what a fit minimises, with one evaluation
    /// of `F` where the distance and [`Self::inside_outside`] would take two (the log-domain
    /// evaluation of a shape with fractional exponents is about ten transcendental calls, and
    /// the learner spends most of its time in it).
    pub fn signed_radial_distance(&self, p: &Vector3<f64>) -> f64 {
        let q = self.untaper(p);
        let lf = self.ln_f_parts(&q).lf;
        if !lf.is_finite() {
            // The centre (ln F = -inf) is inside; a point beyond any scale is outside.
            return if lf == f64::NEG_INFINITY {
                -self.min_size()
            } else {
                self.min_size()
            };
        }
        let s = (-0.5 * self.e1 * lf).exp();
        let d = (p - self.taper(&(q * s))).norm();
        if lf < 0.0 { -d } else { d }
    }

    /// [`Kernel::untapered_surface_along`](super::Kernel::untapered_surface_along) in the log domain.
    pub(crate) fn untapered_surface_along_log(&self, d: &Vector3<f64>) -> Vector3<f64> {
        let lf = self.ln_f_parts(d).lf;
        d * (-0.5 * self.e1 * lf).exp()
    }
}

struct LnParts {
    lu: f64,
    lv: f64,
    ls: f64,
    la: f64,
    lb: f64,
    lf: f64,
}

/// A superquadric placed in a frame (the pose maps local coordinates into that frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedSuperquadric {
    pub shape: Superquadric,
    pub pose: Isometry3<f64>,
}

impl PlacedSuperquadric {
    pub fn new(shape: Superquadric, pose: Isometry3<f64>) -> Self {
        Self { shape, pose }
    }

    /// A frame point in the superquadric's local frame.
    #[inline]
    pub fn to_local(&self, p: &Point3<f64>) -> Vector3<f64> {
        self.pose.inverse_transform_point(p).coords
    }

    /// The residual `F^e1 - 1` of a point given in the frame.
    #[inline]
    pub fn residual(&self, p: &Point3<f64>) -> f64 {
        self.shape.residual(&self.to_local(p))
    }

    /// `F^e1` of a point given in the frame (the quantity the verification thresholds use).
    #[inline]
    pub fn f_pow_e1(&self, p: &Point3<f64>) -> f64 {
        self.shape.f_pow_e1(&self.to_local(p))
    }

    /// Signed distance to the surface of a point given in the frame, to first order (Taubin):
    /// `(F^e1 - 1) / |grad F^e1|`, negative inside. Accurate within a few percent of the size
    /// of the surface and, unlike the radial distance, also for flat shapes seen at their rims;
    /// `-inf` at the centre.
    pub fn surface_distance(&self, p: &Point3<f64>) -> f64 {
        Self::distance_from(&self.shape.residual_grad(&self.to_local(p)))
    }

    /// [`Self::surface_distance`] from the residual and gradient already evaluated at the point.
    #[inline]
    pub fn distance_from(rg: &ResidualGrad) -> f64 {
        let g = rg.grad.norm();
        if g > 0.0 {
            rg.residual / g
        } else if rg.residual < 0.0 {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        }
    }

    /// Radial Euclidean distance of a point given in the frame.
    pub fn radial_distance(&self, p: &Point3<f64>) -> f64 {
        self.shape.radial_distance(&self.to_local(p))
    }

    /// The residual of a frame point and its Jacobian with respect to the 6 pose parameters
    /// `[dtx, dty, dtz, wx, wy, wz]`.
    ///
    /// The parameters are a perturbation of the current pose: a translation `dt` in the frame and
    /// a rotation vector `w` in the local frame, `pose' = (t + dt, R exp([w]x))`. At `w = 0` the
    /// local point is `q = R^T (p - t)`, so `dq/d(dt) = -R^T` and `dq/dw = [q]x` (the rotation of
    /// the body by `w` rotates the point by `-w` in the body frame). Local rotation parameters
    /// make the unobservable spin of a body of revolution exactly the `wz` column, which a 5-DoF
    /// fit simply drops.
    pub fn residual_pose_jacobian(&self, p: &Point3<f64>) -> (f64, [f64; 6]) {
        let q = self.to_local(p);
        let rg = self.shape.residual_grad(&q);
        let g = rg.grad;
        // d r / d(dt) = -g^T R^T = -(R g)^T
        let dt = -(self.pose.rotation * g);
        // d r / d w = g^T [q]x, and g . (q x w) = w . (g x q)
        let dw = g.cross(&q);
        (rg.residual, [dt.x, dt.y, dt.z, dw.x, dw.y, dw.z])
    }

    /// Apply a pose perturbation `[dtx, dty, dtz, wx, wy, wz]` as defined in
    /// [`residual_pose_jacobian`](Self::residual_pose_jacobian).
    pub fn perturbed(&self, delta: &[f64; 6]) -> Self {
        let t = self.pose.translation.vector + Vector3::new(delta[0], delta[1], delta[2]);
        let r =
            self.pose.rotation * nalgebra::UnitQuaternion::from_scaled_axis(Vector3::new(delta[3], delta[4], delta[5]));
        Self {
            shape: self.shape,
            pose: Isometry3::from_parts(t.into(), r),
        }
    }
}
