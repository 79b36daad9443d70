//! The residuals the fit minimises: the visible points (along their rays or to the nearest
//! surface), free space, the support plane, the seen surface, and the score that compares fits.

use super::family::volume;
use super::params::Cost;
use super::seen::{SEEN_SAMPLES, Seen, SeenSample, SeenUnit, seen_local, surface_samples};
use super::state::State;
use crate::cloud::plane::Plane;
use crate::geometry::ray::golden_min;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::numeric::huber;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// The samples of the residuals after the points, in the shape's frame: a change of pose alone
/// reuses them.
pub(super) struct TailLocal {
    /// Surface samples for the lowest point above the support plane.
    bottom: Vec<Vector3<f64>>,
    seen: Vec<SeenSample>,
}

/// Residuals per parallel chunk of an evaluation.
const RESIDUAL_CHUNK: usize = 512;

/// Weight of a free-space violation against a point residual.
pub(super) const FREE_WEIGHT: f64 = 3.0;

/// What the residuals are computed against.
pub(super) struct Problem<'a> {
    pub(super) points: &'a [Point3<f64>],
    /// Points the sensor saw through: samples along the rays to scene points beyond the
    /// object, which must lie outside the surface (free space).
    pub(super) free: &'a [Point3<f64>],
    /// The supporting plane when the bottom must touch it, and the weight of that residual.
    pub(super) support: Option<(Plane, f64)>,
    pub(super) cost: Cost,
    /// Weight of the size term of the "smallest equally good shape" stage: a residual
    /// `w cbrt(V / V0)` (dimensionless, `V0` the volume it started from).
    pub(super) volume: Option<(f64, f64)>,
    /// The surface that faced the sensor must have been seen.
    pub(super) seen: Option<&'a Seen>,
    /// Points that take the distance along their ray ([`ray_read`]) instead of `cost`.
    pub(super) rays: Option<Rays>,
    /// Hold the tapers where they are.
    pub(super) fix_taper: bool,
}

/// Which points take the distance along their ray, and from where.
#[derive(Debug, Clone, Copy)]
pub(super) struct Rays {
    pub(super) viewpoint: Point3<f64>,
    /// The first `seen` points are the sensor's; the rest are their mirrored twins, seen from
    /// the mirrored viewpoint `twin_viewpoint`.
    pub(super) seen: usize,
    pub(super) twin_viewpoint: Point3<f64>,
    /// An open container (see [`ray_read`]).
    pub(super) open: bool,
}

/// Half the window along a point's ray searched for the surface (m): four times the simulated
/// sensor's noise at 1 m. A surface farther off reads as this far.
pub(super) const RAY_WINDOW: f64 = 0.01;
/// Samples over the window: 1.25 mm apart, a quarter of the pen's radius (a ray that crosses
/// less of a part than that grazes it, and the dip of a graze is searched for).
pub(super) const RAY_SAMPLES: usize = 16;

/// [`ray_read`] as a number: `None` when undefined.
#[cfg(test)]
pub(super) fn ray_residual(shape: &Superquadric, q: &Vector3<f64>, d: &Vector3<f64>, open: bool) -> Option<f64> {
    match ray_read(shape, q, d, open) {
        RayRead::Hit(t) | RayRead::Miss { r: t, .. } => Some(t),
        RayRead::Undefined => None,
    }
}

/// What a point's ray reads of the surface ([`ray_read`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum RayRead {
    /// The ray enters the surface this far from the point (the root of the signed radial
    /// distance along the ray): its derivative follows from the implicit function theorem.
    Hit(f64),
    /// The ray passes the surface: `r`, the offset `t` of its closest approach plus the gap there.
    Miss { r: f64, t: f64 },
    /// Through an open container's opening, or deeper inside than the window.
    Undefined,
}

/// The signed distance along the sensor's ray from the point (local `q`, unit ray direction
/// `d` away from the sensor) to the surface where the ray first enters it: negative when the
/// surface is in front of the point. A triangulation sensor's error is along the ray, so this
/// is the point's own error, where the distance to the nearest surface point is not: near an
/// edge a point pushed inside is nearest the face beyond the edge, which pulls that face in and
/// rounds the edge (by about the noise: e1 0.2 where 0.1 is true on a 12 mm shaft). A ray that
/// misses the surface reads the offset of its closest approach plus the gap there, which is
/// continuous with a hit at the grazing ray.
///
/// [`RayRead::Undefined`] for an open container's point whose ray enters through the opening (the inside seen
/// through it is the container's wall, which the solid shape has no surface for), and for a
/// point more than the window inside: such points take the distance to the nearest surface.
pub(super) fn ray_read(shape: &Superquadric, q: &Vector3<f64>, d: &Vector3<f64>, open: bool) -> RayRead {
    let g = |t: f64| shape.signed_radial_distance(&(q + d * t));
    let h = 2.0 * RAY_WINDOW / RAY_SAMPLES as f64;
    let mut prev = (-RAY_WINDOW, g(-RAY_WINDOW));
    if prev.1 <= 0.0 {
        return RayRead::Undefined;
    }
    let entered = |t: f64| {
        let lid = open && crate::model::is_lid(&shape.residual_grad(&(q + d * t)).grad);
        if lid { RayRead::Undefined } else { RayRead::Hit(t) }
    };
    let mut best = prev;
    for i in 1..=RAY_SAMPLES {
        let t = -RAY_WINDOW + h * i as f64;
        let gt = g(t);
        if gt <= 0.0 {
            return entered(ray_refine(&g, prev.0, prev.1, t, gt));
        }
        if gt < best.1 {
            best = (t, gt);
        }
        prev = (t, gt);
    }
    // No sample inside: the closest approach (a grazing ray may dip in between samples).
    let (lo, hi) = ((best.0 - h).max(-RAY_WINDOW), (best.0 + h).min(RAY_WINDOW));
    let (tm, gm) = golden_min(&g, lo, hi, 1e-11);
    if gm <= 0.0 {
        let (ta, ga) = (lo, g(lo));
        return entered(ray_refine(&g, ta, ga, tm, gm));
    }
    RayRead::Miss {
        r: tm + gm.copysign(tm),
        t: tm,
    }
}

/// Illinois regula falsi on `ga > 0 >= gb`, to 1e-12 m: the Jacobian is taken at the root, and
/// its forward-difference fallbacks step down to 1e-7 m. Not `ray`'s refinement, which returns the inside end of the bracket
/// (a hit never short of the surface): the secant of the final bracket is smooth in the
/// shape's parameters, and an exact zero (a sample on the surface, which happens) ends it.
pub(super) fn ray_refine(g: &impl Fn(f64) -> f64, mut ta: f64, mut ga: f64, mut tb: f64, mut gb: f64) -> f64 {
    let mut side = 0i8;
    for _ in 0..60 {
        if tb - ta <= 1e-12 {
            break;
        }
        let t = if ga - gb > 0.0 {
            ((ta * (-gb) + tb * ga) / (ga - gb)).clamp(ta, tb)
        } else {
            0.5 * (ta + tb)
        };
        let gt = g(t);
        if gt == 0.0 {
            return t;
        }
        if gt < 0.0 {
            (tb, gb) = (t, gt);
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        } else {
            (ta, ga) = (t, gt);
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        }
    }
    // The root by the secant of the final bracket (smooth in the parameters).
    if ga - gb > 0.0 {
        (ta * (-gb) + tb * ga) / (ga - gb)
    } else {
        0.5 * (ta + tb)
    }
}

/// The signed first-order distance of a local point to the surface, `g / |grad g|` with
/// `g = F^(e1/2) - 1` (homogeneous of degree 1 along rays from the centre, so it stays finite
/// deep inside and grows linearly outside): from `f = F^e1`, `g = sqrt(f) - 1` and
/// `grad g = grad f / (2 sqrt f)`.
pub(super) fn normal_distance(shape: &Superquadric, q: &Vector3<f64>) -> f64 {
    let rg = shape.residual_grad(q);
    let f = (rg.residual + 1.0).max(0.0);
    let sf = f.sqrt();
    let gn = rg.grad.norm();
    if !(gn > 1e-300) || !sf.is_finite() {
        // The centre or a degenerate point: fall back on the radial distance.
        let d = shape.radial_distance(q);
        return if f < 1.0 { -d } else { d };
    }
    (sf - 1.0) * 2.0 * sf / gn
}

/// 180-degree turn of `p` about the line through `c` along unit `u`.
#[inline]
pub(super) fn turn_half(p: &Point3<f64>, c: &Vector3<f64>, u: &Vector3<f64>) -> Point3<f64> {
    let d = p.coords - c;
    Point3::from(c + 2.0 * u * u.dot(&d) - d)
}

impl Problem<'_> {
    pub(super) fn point_residual(&self, placed: &PlacedSuperquadric, p: &Point3<f64>) -> f64 {
        let q = placed.to_local(p);
        match self.cost {
            // Signed: negative inside, so the Jacobian has no kink on the surface.
            Cost::Radial => placed.shape.signed_radial_distance(&q),
            Cost::Solina => {
                let a = placed.shape.a;
                (a[0] * a[1] * a[2]).sqrt() * placed.shape.residual(&q)
            }
            Cost::Normal => normal_distance(&placed.shape, &q),
        }
    }

    /// Residuals: the points, the free space, then the rest ([`Problem::tail_residuals`]).
    pub(super) fn residuals(&self, s: &State, out: &mut Vec<f64>) {
        self.residuals_read(s, out, None);
    }

    /// [`Problem::residuals`], and what each point's ray read (`None`: the point took
    /// [`Problem::point_residual`]) when `reads` is given.
    pub(super) fn residuals_read(&self, s: &State, out: &mut Vec<f64>, mut reads: Option<&mut Vec<Option<RayRead>>>) {
        out.clear();
        if let Some(r) = reads.as_deref_mut() {
            r.clear();
        }
        let placed = s.placed();
        let to_local = placed.pose.rotation.inverse();
        // Free space outside the shape's bounding sphere is outside it: no residual to evaluate.
        let reach2 = placed.shape.bounding_radius().powi(2);
        let (np, n) = (self.points.len(), self.points.len() + self.free.len());
        // In chunks, in parallel (the later stages fit one start at a time); each residual on
        // its own, so the same values however the chunks are shared out.
        let chunks: Vec<Vec<(f64, Option<RayRead>)>> = (0..n.div_ceil(RESIDUAL_CHUNK))
            .into_par_iter()
            .map(|c| {
                (c * RESIDUAL_CHUNK..((c + 1) * RESIDUAL_CHUNK).min(n))
                    .map(|i| {
                        if i < np {
                            return self.point_read(&placed, &to_local, i);
                        }
                        let p = &self.free[i - np];
                        if (p - placed.pose.translation.vector).coords.norm_squared() > reach2 {
                            (0.0, None)
                        } else {
                            (FREE_WEIGHT * self.point_residual(&placed, p).min(0.0), None)
                        }
                    })
                    .collect()
            })
            .collect();
        for (i, (v, read)) in chunks.into_iter().flatten().enumerate() {
            out.push(v);
            if let Some(r) = reads.as_deref_mut().filter(|_| i < np) {
                r.push(read);
            }
        }
        self.tail_residuals(&placed, out);
    }

    /// The residual of point `i` (`to_local` is the inverse of the placed rotation).
    #[inline]
    pub(super) fn point_value(&self, placed: &PlacedSuperquadric, to_local: &UnitQuaternion<f64>, i: usize) -> f64 {
        self.point_read(placed, to_local, i).0
    }

    /// The residual of point `i` and what its ray read.
    #[inline]
    fn point_read(
        &self,
        placed: &PlacedSuperquadric,
        to_local: &UnitQuaternion<f64>,
        i: usize,
    ) -> (f64, Option<RayRead>) {
        let p = &self.points[i];
        let read = self.ray_of(i).and_then(|(v, open)| {
            (p - v)
                .try_normalize(1e-12)
                .map(|d| ray_read(&placed.shape, &placed.to_local(p), &(to_local * d), open))
        });
        match read {
            Some(RayRead::Hit(t) | RayRead::Miss { r: t, .. }) => (t, read),
            _ => (self.point_residual(placed, p), None),
        }
    }

    /// The viewpoint point `i` takes the distance along its ray from, and whether the shape is
    /// an open container; `None` when it takes [`Problem::point_residual`].
    #[inline]
    pub(super) fn ray_of(&self, i: usize) -> Option<(Point3<f64>, bool)> {
        self.rays
            .map(|r| (if i < r.seen { r.viewpoint } else { r.twin_viewpoint }, r.open))
    }

    /// The residuals after the points and the free space: the support gap, the size term and
    /// the seen surface (a few hundred, however many points).
    pub(super) fn tail_residuals(&self, placed: &PlacedSuperquadric, out: &mut Vec<f64>) {
        self.tail_of(&self.tail_local(&placed.shape, None), placed, out);
    }

    /// What [`Problem::tail_residuals`] samples on a shape, in its own frame; `unit` is reused
    /// when it has the shape's exponents.
    pub(super) fn tail_local(&self, shape: &Superquadric, unit: Option<&SeenUnit>) -> TailLocal {
        let seen = match (self.seen, unit) {
            (None, _) => Vec::new(),
            (Some(_), Some(u)) if u.fits(shape) => seen_local(u, shape),
            (Some(_), _) => seen_local(&SeenUnit::new(shape.e1, shape.e2), shape),
        };
        TailLocal {
            bottom: if self.support.is_some() {
                surface_samples(shape).collect()
            } else {
                Vec::new()
            },
            seen,
        }
    }

    /// [`Problem::tail_residuals`] from the samples of `placed.shape` ([`Problem::tail_local`]).
    pub(super) fn tail_of(&self, local: &TailLocal, placed: &PlacedSuperquadric, out: &mut Vec<f64>) {
        if let Some((plane, w)) = &self.support {
            let gap = local
                .bottom
                .iter()
                .map(|q| plane.signed_distance(&placed.pose.transform_point(&Point3::from(*q))))
                .fold(f64::INFINITY, f64::min);
            out.push(w * gap);
        }
        if let Some((w, v0)) = self.volume {
            out.push(w * (volume(&placed.shape) / v0).cbrt());
        }
        if let Some(seen) = self.seen {
            seen.residuals_of(&local.seen, &placed.pose, out);
        }
    }

    pub(super) fn len(&self) -> usize {
        self.points.len()
            + self.free.len()
            + usize::from(self.support.is_some())
            + usize::from(self.volume.is_some())
            + if self.seen.is_some() { SEEN_SAMPLES } else { 0 }
    }
}

/// The comparable score of a start: Huber loss with a fixed 3 mm threshold over every residual.
pub(super) fn score(problem: &Problem, s: &State) -> f64 {
    let mut r = Vec::new();
    problem.residuals(s, &mut r);
    let delta = match problem.cost {
        Cost::Radial | Cost::Normal => 0.003,
        Cost::Solina => {
            let a = s.shape().a;
            0.05 * (a[0] * a[1] * a[2]).sqrt()
        }
    };
    r.iter()
        .map(|v| if v.is_finite() { huber(*v, delta) } else { 1.0 })
        .sum()
}
