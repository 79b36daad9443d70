//! The residual `F^e1 - 1` and its gradient, prepared once per shape (and pose) and then
//! evaluated for many points: the detector's pose fits, consensus counts and scores spend most
//! of their time here, hundreds of thousands of evaluations a query.
//!
//! What a single evaluation through [`Superquadric`] would work out again for every point is
//! worked out once: the reciprocals of the sizes (a multiplication instead of a division), which
//! exponents are whole numbers (small integer powers are unrolled multiplications), how `F^e1`
//! is taken, and the pose as a rotation matrix. [`Superquadric::residual_grad`] itself goes
//! through a kernel, so there is one implementation of the plain form and the two cannot drift
//! apart.

use super::superquadric::{PlacedSuperquadric, ResidualGrad, Superquadric};
use nalgebra::{Matrix3, Point3, Vector3};

/// How `s^(e2/e1)` is taken in the plain form.
#[derive(Debug, Clone, Copy)]
enum SectionPower {
    /// `s^k`.
    Int(i32),
    /// `s^k sqrt(s)`.
    Half(i32),
    /// A general power.
    Real(f64),
}

/// How `F^e1` is taken.
#[derive(Debug, Clone, Copy)]
enum OuterPower {
    One,
    Sqrt,
    Real(f64),
}

/// The whole-number exponents of the plain form (see [`Superquadric`]'s `plain`).
#[derive(Debug, Clone, Copy)]
struct PlainForm {
    n1: i32,
    n2: i32,
    section: SectionPower,
}

/// A shape prepared for evaluating many points.
#[derive(Debug, Clone, Copy)]
pub struct Kernel {
    shape: Superquadric,
    inv_a: [f64; 3],
    /// Lower clamps of the taper factors (see `Superquadric::taper_factors`).
    clamp: [f64; 2],
    /// `dfx/dz`, `dfy/dz` where the factors are not clamped.
    slope: [f64; 2],
    plain: Option<PlainForm>,
    outer: OuterPower,
    /// `e2 / e1`.
    section_exponent: f64,
    /// No taper: the untaper is the identity (most parts: cylinders, boxes, balls).
    untapered: bool,
}

/// Points farther than this many sizes along an axis leave the plain form (their integer powers
/// could overflow) for the log domain.
const PLAIN_REACH: f64 = 1e4;

impl Kernel {
    pub fn new(shape: &Superquadric) -> Kernel {
        let plain = match (int_exponent(2.0 / shape.e1), int_exponent(2.0 / shape.e2)) {
            (Some(n1), Some(n2)) => {
                let m = shape.e2 / shape.e1;
                // e2/e1 is often a whole or a half number (1/0.4 = 2.5): s^(k/2) = s^(k div 2)
                // sqrt(s) costs a fraction of a general power.
                let section = match int_exponent(2.0 * m) {
                    Some(k) if k % 2 == 0 => SectionPower::Int(k / 2),
                    Some(k) => SectionPower::Half(k / 2),
                    None => SectionPower::Real(m),
                };
                Some(PlainForm { n1, n2, section })
            }
            _ => None,
        };
        let outer = if shape.e1 == 1.0 {
            OuterPower::One
        } else if shape.e1 == 0.5 {
            OuterPower::Sqrt
        } else {
            OuterPower::Real(shape.e1)
        };
        Kernel {
            shape: *shape,
            inv_a: shape.a.map(|a| 1.0 / a),
            clamp: [0.5 * (1.0 - shape.kx.abs()), 0.5 * (1.0 - shape.ky.abs())],
            slope: [shape.kx / shape.a[2], shape.ky / shape.a[2]],
            plain,
            outer,
            section_exponent: shape.e2 / shape.e1,
            untapered: shape.kx == 0.0 && shape.ky == 0.0,
        }
    }

    pub fn shape(&self) -> &Superquadric {
        &self.shape
    }

    /// `F^e1` from `F`.
    #[inline(always)]
    fn pow_e1(&self, f: f64) -> f64 {
        match self.outer {
            OuterPower::One => f,
            OuterPower::Sqrt => f.sqrt(),
            // exp(e1 ln F) is two of libm's fast paths, where `powf` takes its general one; the
            // two differ by a few units in the last place.
            OuterPower::Real(e1) if f > 0.0 => (e1 * f.ln()).exp(),
            OuterPower::Real(e1) => f.powf(e1),
        }
    }

    /// The taper factors at height `z` and whether each is clamped.
    #[inline(always)]
    fn taper(&self, z: f64) -> ([f64; 2], [bool; 2]) {
        let t = z * self.inv_a[2];
        let rx = self.shape.kx * t + 1.0;
        let ry = self.shape.ky * t + 1.0;
        (
            [rx.max(self.clamp[0]), ry.max(self.clamp[1])],
            [rx <= self.clamp[0], ry <= self.clamp[1]],
        )
    }

    /// The surface point in the untapered frame in unit direction `d` from the centre.
    #[inline]
    pub fn untapered_surface_along(&self, d: &Vector3<f64>) -> Vector3<f64> {
        // F is homogeneous of degree 2/e1 along a ray: the surface lies at t = F(d)^(-e1/2).
        // With integer exponents F(d) is a few multiplications and one power, where the log
        // domain takes about ten transcendental calls; surface sampling (the detector's coverage
        // samples, the simulator's placement) spends nearly all its time here.
        if let Some(pf) = &self.plain {
            let r = [
                d.x.abs() * self.inv_a[0],
                d.y.abs() * self.inv_a[1],
                d.z.abs() * self.inv_a[2],
            ];
            if r[0] <= PLAIN_REACH && r[1] <= PLAIN_REACH && r[2] <= PLAIN_REACH {
                let s = ipow(r[0], pf.n2) + ipow(r[1], pf.n2);
                let f = section_power(s, pf.section) + ipow(r[2], pf.n1);
                if f.is_finite() && f > 0.0 {
                    let t = match self.outer {
                        OuterPower::One => 1.0 / f.sqrt(),
                        OuterPower::Sqrt => 1.0 / f.sqrt().sqrt(),
                        OuterPower::Real(e1) => (-0.5 * e1 * f.ln()).exp(),
                    };
                    return d * t;
                }
            }
        }
        self.shape.untapered_surface_along_log(d)
    }

    /// Apply the taper to an untapered local point.
    #[inline]
    pub fn taper_point(&self, q: &Vector3<f64>) -> Vector3<f64> {
        let ([fx, fy], _) = self.taper(q.z);
        Vector3::new(q.x * fx, q.y * fy, q.z)
    }

    /// The residual `F^e1 - 1` of a local point.
    #[inline]
    pub fn residual(&self, p: &Vector3<f64>) -> f64 {
        let ([fx, fy], _) = self.taper(p.z);
        let q = Vector3::new(p.x / fx, p.y / fy, p.z);
        if let Some(pf) = &self.plain {
            let r = [
                q.x.abs() * self.inv_a[0],
                q.y.abs() * self.inv_a[1],
                q.z.abs() * self.inv_a[2],
            ];
            if r[0] <= PLAIN_REACH && r[1] <= PLAIN_REACH && r[2] <= PLAIN_REACH {
                let s = ipow(r[0], pf.n2) + ipow(r[1], pf.n2);
                return self.pow_e1(section_power(s, pf.section) + ipow(r[2], pf.n1)) - 1.0;
            }
        }
        self.shape.residual_log(&q)
    }

    /// The residual and its gradient with respect to the local point coordinates.
    #[inline]
    pub fn residual_grad(&self, p: &Vector3<f64>) -> ResidualGrad {
        if self.untapered {
            let (g, gx, gy, gz) = match self.plain_grad(p) {
                Some(v) => v,
                None => match self.shape.log_grad_untapered(p) {
                    Some(v) => v,
                    None => {
                        return ResidualGrad {
                            residual: self.shape.residual_log(p),
                            grad: Vector3::zeros(),
                        };
                    }
                },
            };
            return ResidualGrad {
                residual: g - 1.0,
                grad: Vector3::new(gx, gy, gz),
            };
        }
        let ([fx, fy], clamped) = self.taper(p.z);
        let (ix, iy) = (1.0 / fx, 1.0 / fy);
        let q = Vector3::new(p.x * ix, p.y * iy, p.z);
        let (g, gx, gy, gz) = match self.plain_grad(&q) {
            Some(v) => v,
            None => match self.shape.log_grad_untapered(&q) {
                Some(v) => v,
                None => {
                    return ResidualGrad {
                        residual: self.shape.residual_log(&q),
                        grad: Vector3::zeros(),
                    };
                }
            },
        };
        // Chain through the untaper x = X / fx(Z): dx/dX = 1/fx, dx/dZ = -x (dfx/dZ) / fx. Where
        // the factor is clamped it does not depend on Z.
        let dfx = if clamped[0] { 0.0 } else { self.slope[0] };
        let dfy = if clamped[1] { 0.0 } else { self.slope[1] };
        ResidualGrad {
            residual: g - 1.0,
            grad: Vector3::new(gx * ix, gy * iy, gz - gx * q.x * dfx * ix - gy * q.y * dfy * iy),
        }
    }

    /// `F^e1` and its gradient in the untapered frame, plain form; `None` where the plain form
    /// does not apply.
    #[inline(always)]
    fn plain_grad(&self, q: &Vector3<f64>) -> Option<(f64, f64, f64, f64)> {
        let pf = self.plain.as_ref()?;
        let r = [
            q.x.abs() * self.inv_a[0],
            q.y.abs() * self.inv_a[1],
            q.z.abs() * self.inv_a[2],
        ];
        if r[0] > PLAIN_REACH || r[1] > PLAIN_REACH || r[2] > PLAIN_REACH {
            return None;
        }
        let u = ipow(r[0], pf.n2);
        let v = ipow(r[1], pf.n2);
        let s = u + v;
        let a = section_power(s, pf.section);
        let b = ipow(r[2], pf.n1);
        let f = a + b;
        let g = self.pow_e1(f);
        if f == 0.0 {
            return Some((g, 0.0, 0.0, 0.0));
        }
        let e1 = self.shape.e1;
        let dg_df = e1 * g / f;
        let da_ds = if s > 0.0 { self.section_exponent * a / s } else { 0.0 };
        // d(r^n)/dq = n r^(n-1) sign(q) / a, with r = |q| / a; r^(n-1) = r^n / r from the value
        // already computed (no second integer power).
        let d = |r: f64, rn: f64, n: i32, c: f64, inv_a: f64| {
            if n == 1 {
                c.signum() * inv_a
            } else if c == 0.0 || r == 0.0 {
                0.0
            } else {
                n as f64 * (rn / r) * c.signum() * inv_a
            }
        };
        let gx = dg_df * da_ds * d(r[0], u, pf.n2, q.x, self.inv_a[0]);
        let gy = dg_df * da_ds * d(r[1], v, pf.n2, q.y, self.inv_a[1]);
        let gz = dg_df * d(r[2], b, pf.n1, q.z, self.inv_a[2]);
        Some((g, gx, gy, gz))
    }
}

/// A placed shape prepared for evaluating many points given in the frame its pose maps into.
#[derive(Debug, Clone, Copy)]
pub struct PlacedKernel {
    pub kernel: Kernel,
    /// The pose's rotation (local to frame) and translation.
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
    /// Half-sizes of the local box the shape lies in.
    half_extents: Vector3<f64>,
}

impl PlacedKernel {
    pub fn new(placed: &PlacedSuperquadric) -> PlacedKernel {
        PlacedKernel {
            kernel: Kernel::new(&placed.shape),
            rotation: placed.pose.rotation.to_rotation_matrix().into_inner(),
            translation: placed.pose.translation.vector,
            half_extents: placed.shape.local_half_extents(),
        }
    }

    /// [`Self::surface_distance`] of a frame point within `band` of the shape's local box, `None`
    /// for a point outside it: no point of the surface lies within `band` of such a point, and a
    /// box test is a tenth of the cost of the distance.
    #[inline]
    pub fn surface_distance_near(&self, p: &Point3<f64>, band: f64) -> Option<f64> {
        let q = self.to_local(p);
        if q.x.abs() > self.half_extents.x + band
            || q.y.abs() > self.half_extents.y + band
            || q.z.abs() > self.half_extents.z + band
        {
            return None;
        }
        Some(PlacedSuperquadric::distance_from(&self.kernel.residual_grad(&q)))
    }

    /// A frame point in the local frame.
    #[inline(always)]
    pub fn to_local(&self, p: &Point3<f64>) -> Vector3<f64> {
        self.rotation.tr_mul(&(p.coords - self.translation))
    }

    /// The residual `F^e1 - 1` of a frame point.
    #[inline]
    pub fn residual(&self, p: &Point3<f64>) -> f64 {
        self.kernel.residual(&self.to_local(p))
    }

    /// Signed first-order distance to the surface (see [`PlacedSuperquadric::surface_distance`]).
    #[inline]
    pub fn surface_distance(&self, p: &Point3<f64>) -> f64 {
        PlacedSuperquadric::distance_from(&self.kernel.residual_grad(&self.to_local(p)))
    }

    /// The residual and its Jacobian with respect to the pose perturbation (see
    /// [`PlacedSuperquadric::residual_pose_jacobian`]).
    #[inline]
    pub fn residual_pose_jacobian(&self, p: &Point3<f64>) -> (f64, [f64; 6]) {
        let q = self.to_local(p);
        let rg = self.kernel.residual_grad(&q);
        let g = rg.grad;
        let dt = -(self.rotation * g);
        let dw = g.cross(&q);
        (rg.residual, [dt.x, dt.y, dt.z, dw.x, dw.y, dw.z])
    }
}

#[inline(always)]
fn section_power(s: f64, p: SectionPower) -> f64 {
    match p {
        SectionPower::Int(k) => ipow(s, k),
        SectionPower::Half(k) => ipow(s, k) * s.sqrt(),
        SectionPower::Real(m) => s.powf(m),
    }
}

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
