//! Ray queries against a tapered superquadric.
//!
//! A superquadric has no closed-form ray intersection, so the ray is clipped to the shape's
//! bounding box, marched in steps a fraction of the smallest size (no part of the solid is
//! thinner than twice that along any axis), a dip of the residual between two outside samples is
//! searched for a grazing crossing, and the first step that lands inside is refined by
//! the Illinois variant of regula falsi on the residual, which is close to linear in the distance
//! near the surface.

use super::Superquadric;
use super::superquadric::PlacedSuperquadric;
use nalgebra::{Point3, Vector3};

/// Steps per smallest half-size while marching; grazing rays that dip in and out between two
/// samples are caught by a golden-section search of the dip.
const STEPS_PER_MIN_SIZE: f64 = 4.0;
/// Refinement stops when the bracket is this small (m).
const T_TOLERANCE: f64 = 1e-8;

impl Superquadric {
    /// The smallest `t` in `[0, t_max]` at which `origin + t dir` is inside or on the surface, in
    /// the local frame. `dir` need not be unit length (`t` is in units of `|dir|`). A ray that
    /// starts inside returns `Some(0)`.
    pub fn ray_hit(&self, origin: &Vector3<f64>, dir: &Vector3<f64>, t_max: f64) -> Option<f64> {
        let dir_len = dir.norm();
        // Written so that a NaN length or limit takes the early return.
        let usable = dir_len > 0.0 && dir_len.is_finite() && t_max >= 0.0;
        if !usable {
            return None;
        }
        // Clip to the bounding box, slightly grown so the surface never sits on the clip points.
        let h = self.local_half_extents() * 1.001;
        let (mut t0, mut t1) = (0.0f64, t_max);
        for i in 0..3 {
            let (o, d) = (origin[i], dir[i]);
            if d.abs() < 1e-300 {
                if o.abs() > h[i] {
                    return None;
                }
            } else {
                let (a, b) = ((-h[i] - o) / d, (h[i] - o) / d);
                let (a, b) = if a < b { (a, b) } else { (b, a) };
                t0 = t0.max(a);
                t1 = t1.min(b);
                if t0 > t1 {
                    return None;
                }
            }
        }
        let f = |t: f64| self.residual(&(origin + dir * t));
        let mut ta = t0;
        let mut fa = f(ta);
        if fa <= 0.0 {
            return Some(ta);
        }
        let step = self.min_size() / STEPS_PER_MIN_SIZE / dir_len;
        // The previous sample, to notice a dip of the residual between samples: a ray that only
        // grazes the surface can enter and leave it between two samples that are both outside.
        let (mut tp, mut fp) = (ta, f64::INFINITY);
        while ta < t1 {
            let tb = (ta + step).min(t1);
            let fb = f(tb);
            if fb <= 0.0 {
                return Some(refine(&f, ta, fa, tb, fb));
            }
            if fa < fp && fa < fb && fa < GRAZE_RESIDUAL {
                let (tm, fm) = golden_min(&f, tp, tb, T_TOLERANCE);
                if fm <= 0.0 {
                    // Every sample so far was outside, so the first crossing lies in [tp, tm].
                    return Some(refine(&f, tp, f(tp), tm, fm));
                }
            }
            (tp, fp) = (ta, fa);
            ta = tb;
            fa = fb;
        }
        None
    }
}

/// Below this residual a local dip between samples is searched for a hidden crossing; far from
/// the surface the residual cannot dip below zero between samples one step apart.
const GRAZE_RESIDUAL: f64 = 0.5;

/// Golden-section search for the minimum of `f` on `[a, b]` (to a bracket of `tolerance`),
/// stopping early once `f <= 0`.
pub(crate) fn golden_min(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64, tolerance: f64) -> (f64, f64) {
    const R: f64 = 0.618_033_988_749_895;
    let mut c = b - R * (b - a);
    let mut d = a + R * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc <= 0.0 {
            return (c, fc);
        }
        if fd <= 0.0 {
            return (d, fd);
        }
        if b - a <= tolerance {
            break;
        }
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - R * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + R * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { (c, fc) } else { (d, fd) }
}

/// Illinois regula falsi on a bracket with `fa > 0 >= fb`; returns a `t` with `f(t) <= 0` (the
/// inside end), so a hit is never reported short of the surface.
fn refine(f: &impl Fn(f64) -> f64, mut ta: f64, mut fa: f64, mut tb: f64, mut fb: f64) -> f64 {
    let mut side = 0i8;
    for _ in 0..100 {
        if tb - ta <= T_TOLERANCE {
            break;
        }
        let t = if fa - fb > 0.0 {
            (ta * (-fb) + tb * fa) / (fa - fb)
        } else {
            0.5 * (ta + tb)
        };
        let t = t.clamp(ta, tb);
        let ft = f(t);
        if ft <= 0.0 {
            tb = t;
            fb = ft;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        } else {
            ta = t;
            fa = ft;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        }
    }
    tb
}

impl PlacedSuperquadric {
    /// The first hit of a ray given in the pose's frame, as a distance along `dir` (in units of
    /// `|dir|`), within `[0, t_max]`.
    pub fn ray_hit(&self, origin: &Point3<f64>, dir: &Vector3<f64>, t_max: f64) -> Option<f64> {
        let o = self.pose.inverse_transform_point(origin).coords;
        let d = self.pose.inverse_transform_vector(dir);
        self.shape.ray_hit(&o, &d, t_max)
    }
}
