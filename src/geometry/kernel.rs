//! The residual `F^e1 - 1` and its gradient, prepared once per shape (and pose) and then
//! evaluated for many points: the detector's pose fits, consensus counts and scores spend most
//! of their time here, hundreds of thousands of evaluations a query.
//!
//! What a single evaluation through [`Superquadric`] would work out again for every point is
//! worked out once: the reciprocals of the sizes (a multiplication instead of a division), which
//! exponents are whole numbers (small integer powers are unrolled multiplications), how `F^e1`
//! is taken; for a placed shape (`placed`), the pose as a rotation matrix.
//! [`Superquadric::residual_grad`] itself goes through a kernel, so there is one implementation
//! of the plain form and the two cannot drift apart.

use super::powers::int_exponent;
use super::superquadric::{ResidualGrad, Superquadric};
use crate::numeric::lanes::{Lanes, Mask};
use nalgebra::{Point3, Vector3};

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
    pub(super) shape: Superquadric,
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

impl Superquadric {
    /// The residual and its gradient with respect to the local point coordinates. (Through a
    /// [`Kernel`]: to evaluate many points of one shape, make one and keep it.)
    pub fn residual_grad(&self, p: &Vector3<f64>) -> ResidualGrad {
        Kernel::new(self).residual_grad(p)
    }
}

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
        let [x, y, z] = self.untapered_surface_along_lanes([Lanes([d.x]), Lanes([d.y]), Lanes([d.z])]);
        Vector3::new(x.0[0], y.0[0], z.0[0])
    }

    /// [`Self::untapered_surface_along`] of `L` unit directions at once, the same to the bit.
    #[inline(always)]
    pub fn untapered_surface_along_lanes<const L: usize>(&self, d: [Lanes<L>; 3]) -> [Lanes<L>; 3] {
        // F is homogeneous of degree 2/e1 along a ray: the surface lies at t = F(d)^(-e1/2).
        // With integer exponents F(d) is a few multiplications and one power, where the log
        // domain takes about ten transcendental calls; surface sampling (the detector's coverage
        // samples, the simulator's placement) spends nearly all its time here.
        let mut ok = Mask([false; L]);
        let mut out = d;
        if let Some(pf) = &self.plain {
            let r: [Lanes<L>; 3] = std::array::from_fn(|k| d[k].abs() * self.inv_a[k]);
            let s = ipow_lanes(r[0], pf.n2) + ipow_lanes(r[1], pf.n2);
            let a = match pf.section {
                SectionPower::Int(k) => ipow_lanes(s, k),
                SectionPower::Half(k) => ipow_lanes(s, k) * s.sqrt(),
                SectionPower::Real(m) => s.powf_pos(m),
            };
            let f = a + ipow_lanes(r[2], pf.n1);
            let one = Lanes::splat(1.0);
            let t = match self.outer {
                OuterPower::One => one / f.sqrt(),
                OuterPower::Sqrt => one / f.sqrt().sqrt(),
                OuterPower::Real(e1) => (f.ln() * (-0.5 * e1)).exp(),
            };
            out = d.map(|c| c * t);
            for i in 0..L {
                ok.0[i] = r.iter().all(|r| r.0[i] <= PLAIN_REACH) && f.0[i].is_finite() && f.0[i] > 0.0;
            }
        }
        for i in 0..L {
            if !ok.0[i] {
                let q = self
                    .shape
                    .untapered_surface_along_log(&Vector3::new(d[0].0[i], d[1].0[i], d[2].0[i]));
                for k in 0..3 {
                    out[k].0[i] = q[k];
                }
            }
        }
        out
    }

    /// [`Self::taper_point`] of `L` points at once.
    #[inline(always)]
    pub fn taper_lanes<const L: usize>(&self, q: [Lanes<L>; 3]) -> [Lanes<L>; 3] {
        if self.untapered {
            return q;
        }
        let t = q[2] * self.inv_a[2];
        let fx = (t * self.shape.kx + 1.0).max(Lanes::splat(self.clamp[0]));
        let fy = (t * self.shape.ky + 1.0).max(Lanes::splat(self.clamp[1]));
        [q[0] * fx, q[1] * fy, q[2]]
    }

    /// Apply the taper to an untapered local point.
    #[inline]
    pub fn taper_point(&self, q: &Vector3<f64>) -> Vector3<f64> {
        let ([fx, fy], _) = self.taper(q.z);
        Vector3::new(q.x * fx, q.y * fy, q.z)
    }

    /// The residual `F^e1 - 1` of a local point (the same as [`Self::residual_grad`]'s).
    #[inline]
    pub fn residual(&self, p: &Vector3<f64>) -> f64 {
        if let Some(pf) = &self.plain {
            let (r, _, far) = self.plain_lanes(pf, [Lanes([p.x]), Lanes([p.y]), Lanes([p.z])]);
            if !far.0[0] {
                return r.0[0];
            }
        }
        let ([fx, fy], _) = self.taper(p.z);
        self.shape.residual_log(&Vector3::new(p.x / fx, p.y / fy, p.z))
    }

    /// The residual and its gradient with respect to the local point coordinates.
    #[inline]
    pub fn residual_grad(&self, p: &Vector3<f64>) -> ResidualGrad {
        let (r, [gx, gy, gz]) = self.residual_grad_lanes([Lanes([p.x]), Lanes([p.y]), Lanes([p.z])]);
        ResidualGrad {
            residual: r.0[0],
            grad: Vector3::new(gx.0[0], gy.0[0], gz.0[0]),
        }
    }

    /// [`Self::residual_grad`] of `L` local points at once (their x, y and z coordinates), the
    /// same to the bit as one at a time.
    #[inline(always)]
    pub fn residual_grad_lanes<const L: usize>(&self, p: [Lanes<L>; 3]) -> (Lanes<L>, [Lanes<L>; 3]) {
        let Some(pf) = &self.plain else {
            return self.log_lanes(p, Mask([true; L]), (Lanes::splat(0.0), [Lanes::splat(0.0); 3]));
        };
        let (r, g, far) = self.plain_lanes(pf, p);
        if far.any() {
            return self.log_lanes(p, far, (r, g));
        }
        (r, g)
    }

    /// The lanes of `into` the mask selects, replaced by the log-domain evaluation: for shapes
    /// without a plain form, and for points beyond its reach.
    #[cold]
    fn log_lanes<const L: usize>(
        &self,
        p: [Lanes<L>; 3],
        which: Mask<L>,
        into: (Lanes<L>, [Lanes<L>; 3]),
    ) -> (Lanes<L>, [Lanes<L>; 3]) {
        let (mut r, mut g) = into;
        for i in 0..L {
            if which.0[i] {
                let rg = self.residual_grad_log(&Vector3::new(p[0].0[i], p[1].0[i], p[2].0[i]));
                r.0[i] = rg.residual;
                for k in 0..3 {
                    g[k].0[i] = rg.grad[k];
                }
            }
        }
        (r, g)
    }

    /// The residual and gradient through the log domain (any exponents, any distance).
    fn residual_grad_log(&self, p: &Vector3<f64>) -> ResidualGrad {
        let ([fx, fy], clamped) = self.taper(p.z);
        let (ix, iy) = (1.0 / fx, 1.0 / fy);
        let q = Vector3::new(p.x * ix, p.y * iy, p.z);
        let Some((g, gx, gy, gz)) = self.shape.log_grad_untapered(&q) else {
            return ResidualGrad {
                residual: self.shape.residual_log(&q),
                grad: Vector3::zeros(),
            };
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

    /// The residual and gradient in the plain form, branch-free across the lanes, and which
    /// lanes lie beyond its reach (their values are not to be used).
    #[inline(always)]
    fn plain_lanes<const L: usize>(&self, pf: &PlainForm, p: [Lanes<L>; 3]) -> (Lanes<L>, [Lanes<L>; 3], Mask<L>) {
        let zero = Lanes::splat(0.0);
        let [px, py, pz] = p;
        // The untaper x = X / fx(Z), and dfx/dZ where the factor is not clamped.
        let (qx, qy, ix, iy, dfx, dfy) = if self.untapered {
            (px, py, Lanes::splat(1.0), Lanes::splat(1.0), zero, zero)
        } else {
            let t = pz * self.inv_a[2];
            let rx = t * self.shape.kx + 1.0;
            let ry = t * self.shape.ky + 1.0;
            let (cx, cy) = (Lanes::splat(self.clamp[0]), Lanes::splat(self.clamp[1]));
            let ix = Lanes::splat(1.0) / rx.max(cx);
            let iy = Lanes::splat(1.0) / ry.max(cy);
            let dfx = Mask::select(rx.le(cx), zero, Lanes::splat(self.slope[0]));
            let dfy = Mask::select(ry.le(cy), zero, Lanes::splat(self.slope[1]));
            (px * ix, py * iy, ix, iy, dfx, dfy)
        };
        let r0 = qx.abs() * self.inv_a[0];
        let r1 = qy.abs() * self.inv_a[1];
        let r2 = pz.abs() * self.inv_a[2];
        let reach = Lanes::splat(PLAIN_REACH);
        let far = reach.lt(r0).or(reach.lt(r1)).or(reach.lt(r2));
        // r^(n-1) and r^n: the first is the derivative's, the second one product more.
        let u1 = ipow_lanes(r0, pf.n2 - 1);
        let v1 = ipow_lanes(r1, pf.n2 - 1);
        let b1 = ipow_lanes(r2, pf.n1 - 1);
        let (u, v, b) = (u1 * r0, v1 * r1, b1 * r2);
        let s = u + v;
        let a = match pf.section {
            SectionPower::Int(k) => ipow_lanes(s, k),
            SectionPower::Half(k) => ipow_lanes(s, k) * s.sqrt(),
            SectionPower::Real(m) => s.powf_pos(m),
        };
        let f = a + b;
        let g = match self.outer {
            OuterPower::One => f,
            OuterPower::Sqrt => f.sqrt(),
            OuterPower::Real(e1) => f.powf_pos(e1),
        };
        let dg_df = Mask::select(f.eq(zero), zero, g * self.shape.e1 / f);
        let da_ds = Mask::select(s.eq(zero), zero, a * self.section_exponent / s);
        // d(r^n)/dq = n r^(n-1) sign(q) / a.
        let dgx = (dg_df * da_ds * u1 * (pf.n2 as f64 * self.inv_a[0])).copysign(qx);
        let dgy = (dg_df * da_ds * v1 * (pf.n2 as f64 * self.inv_a[1])).copysign(qy);
        let dgz = (dg_df * b1 * (pf.n1 as f64 * self.inv_a[2])).copysign(pz);
        // Chain through the untaper: dx/dX = 1/fx, dx/dZ = -x (dfx/dZ) / fx.
        let grad = [dgx * ix, dgy * iy, dgz - dgx * qx * dfx * ix - dgy * qy * dfy * iy];
        (g - 1.0, grad, far)
    }
}

/// [`ipow`](super::powers::ipow) of each lane (`n` is the same for all, so the choice is made once).
#[inline(always)]
pub(super) fn ipow_lanes<const L: usize>(x: Lanes<L>, n: i32) -> Lanes<L> {
    match n {
        0 => Lanes::splat(1.0),
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
        // The exponents of e = 0.1 (2/e = 20, its section power 10, the derivative's 19), in the
        // order of the square and multiply below, so that the bits are the same.
        10 => {
            let x2 = x * x;
            let x8 = {
                let x4 = x2 * x2;
                x4 * x4
            };
            x2 * x8
        }
        19 | 20 => {
            let x2 = x * x;
            let x4 = x2 * x2;
            let x16 = {
                let x8 = x4 * x4;
                x8 * x8
            };
            if n == 19 { x * x2 * x16 } else { x4 * x16 }
        }
        n if n > 0 => {
            // Square and multiply, the same steps in every lane.
            let (mut acc, mut base, mut e) = (Lanes::splat(1.0), x, n as u32);
            loop {
                if e & 1 == 1 {
                    acc = acc * base;
                }
                e >>= 1;
                if e == 0 {
                    return acc;
                }
                base = base * base;
            }
        }
        _ => x.map(|x| x.powi(n)),
    }
}

/// The x, y and z coordinates of `L` points as lanes.
#[inline(always)]
pub fn lanes_of<const L: usize>(points: &[Point3<f64>]) -> [Lanes<L>; 3] {
    std::array::from_fn(|k| Lanes(std::array::from_fn(|i| points[i][k])))
}
