//! What the sensor saw besides the points: free space along rays that passed the object, the
//! surface that faced the sensor and so must have been seen, and the silhouette.

use crate::cloud::plane::Plane;
#[cfg(test)]
use crate::geometry::Kernel;
use crate::geometry::{PlacedSuperquadric, Superquadric, logsumexp};
use nalgebra::{Isometry3, Point3, Vector3};

/// The counterpart of free space: surface that faces the sensor squarely (and is above the
/// table) would have been seen, so an object point must lie near it. Without this a shape is
/// free to put surface where the view shows nothing: a bowl's hidden foot tapered to a cone
/// whose flank would face the sensor, the back of a segmented can blown up sideways.
pub(super) struct Seen {
    pub(super) viewpoint: Point3<f64>,
    /// The visible object points and a grid over them.
    pub(super) points: Vec<Point3<f64>>,
    pub(super) grid: crate::cloud::grid::Grid,
    /// A finer grid for the common case, a sample within [`SEEN_TOLERANCE`] of a point.
    pub(super) near: crate::cloud::grid::Grid,
    pub(super) plane: Option<Plane>,
    /// An open container: its lid is not surface.
    pub(super) open: bool,
    /// Weight of one surface sample's residual.
    pub(super) weight: f64,
}

/// Surface facing the sensor at a smaller incidence than this is expected in the data; the
/// residual ramps in from [`SEEN_COS_FROM`] (triangulation sensors return up to about 80 deg,
/// the simulated one too; the margin leaves grazing surface, which noise and dropout thin out,
/// alone).
pub(super) const SEEN_COS_FULL: f64 = 0.5; // 60 deg
pub(super) const SEEN_COS_FROM: f64 = 0.259; // 75 deg
/// A facing surface sample this close to an object point is seen.
pub(super) const SEEN_TOLERANCE: f64 = 0.006;
/// Nearest points are looked for within this radius (a sample farther off counts as this far).
pub(super) const SEEN_RADIUS: f64 = 0.03;

impl Seen {
    pub(super) fn new(viewpoint: Point3<f64>, points: &[Point3<f64>], plane: Option<&Plane>, open: bool) -> Seen {
        let samples = SEEN_SAMPLES as f64;
        Seen {
            viewpoint,
            points: points.to_vec(),
            grid: crate::cloud::grid::Grid::new(points, SEEN_RADIUS),
            near: crate::cloud::grid::Grid::new(points, SEEN_TOLERANCE),
            plane: plane.copied(),
            open,
            // The samples together weigh like half the points.
            weight: (0.5 * points.len() as f64 / samples).sqrt(),
        }
    }

    /// The residuals of the local samples of [`seen_local`] placed at `pose` (a change of pose
    /// alone moves the samples without re-sampling the surface).
    pub(super) fn residuals_of(&self, local: &[SeenSample], pose: &Isometry3<f64>, out: &mut Vec<f64>) {
        for sample in local {
            let p = pose.transform_point(&Point3::from(sample.q));
            if self.open && sample.lid {
                out.push(0.0);
                continue;
            }
            let (Some(n), Some(to_sensor)) = (
                (pose.rotation * sample.grad).try_normalize(1e-300),
                (self.viewpoint - p).try_normalize(1e-12),
            ) else {
                out.push(0.0);
                continue;
            };
            let ramp = ((n.dot(&to_sensor) - SEEN_COS_FROM) / (SEEN_COS_FULL - SEEN_COS_FROM)).clamp(0.0, 1.0);
            let above = self.plane.is_none_or(|pl| pl.signed_distance(&p) > 0.005);
            if ramp == 0.0 || !above {
                out.push(0.0);
                continue;
            }
            if self.near.any_within(&self.points, &p, SEEN_TOLERANCE) {
                out.push(0.0);
                continue;
            }
            let mut d2 = SEEN_RADIUS * SEEN_RADIUS;
            self.grid.for_each_within(&self.points, &p, SEEN_RADIUS, |i| {
                d2 = d2.min((self.points[i] - p).norm_squared());
            });
            out.push(self.weight * ramp * (d2.sqrt() - SEEN_TOLERANCE).max(0.0));
        }
    }
}

/// A seen-surface sample in the shape's frame: the point, the residual's gradient there (the
/// outward normal, any length) and whether that normal is a lid's.
#[derive(Debug, Clone, Copy)]
pub(super) struct SeenSample {
    q: Vector3<f64>,
    grad: Vector3<f64>,
    lid: bool,
}

/// What the seen samples of a shape owe to its exponents alone. Along the direction `c * a`
/// (`c` a point of the grid on the unit cube's faces, `*` per axis) the untapered surface lies
/// at `t (c * a)` with `t = F(c)^(-e1/2)` (F is homogeneous of degree `2/e1` and
/// `F(c * a) = F(c)` with the sizes as units), and its gradient there is parallel to
/// `u / a` (per axis) with `u` from `c` and the exponents alone. So the sizes and the tapers
/// scale and shear these (the forward differences of five of the seven shape parameters need
/// no logarithm), and only a change of exponent recomputes them.
pub(super) struct SeenUnit {
    e: (f64, f64),
    /// Per sample: `c`, `t` and `u`.
    samples: Vec<(Vector3<f64>, f64, Vector3<f64>)>,
}

impl SeenUnit {
    pub(super) fn new(e1: f64, e2: f64) -> SeenUnit {
        let samples = seen_directions()
            .map(|c| {
                let ln = |v: f64| v.abs().ln();
                let lu = (2.0 / e2) * ln(c.x);
                let lv = (2.0 / e2) * ln(c.y);
                let ls = logsumexp(lu, lv);
                let la = (e2 / e1) * ls;
                let lb = (2.0 / e1) * ln(c.z);
                let lf = logsumexp(la, lb);
                let t = (-0.5 * e1 * lf).exp();
                // d ln F / d ln|x| = (2/e1) wA wU and so on: the weights of the log-sum-exps.
                let (wa, wb) = ((la - lf).exp(), (lb - lf).exp());
                let (wu, wv) = if ls == f64::NEG_INFINITY {
                    (0.0, 0.0)
                } else {
                    ((lu - ls).exp(), (lv - ls).exp())
                };
                let part = |w: f64, c: f64| if c == 0.0 { 0.0 } else { w / c };
                (
                    c,
                    t,
                    Vector3::new(part(wa * wu, c.x), part(wa * wv, c.y), part(wb, c.z)),
                )
            })
            .collect();
        SeenUnit { e: (e1, e2), samples }
    }

    /// Whether these are `sq`'s exponents.
    pub(super) fn fits(&self, sq: &Superquadric) -> bool {
        self.e == (sq.e1, sq.e2)
    }
}

/// The seen samples of `sq` with their normals, from its exponents' [`SeenUnit`].
pub(super) fn seen_local(unit: &SeenUnit, sq: &Superquadric) -> Vec<SeenSample> {
    let a = Vector3::from(sq.a);
    unit.samples
        .iter()
        .map(|(c, t, u)| {
            let qu = c.component_mul(&a) * *t;
            let q = sq.taper(&qu);
            let gu = u.component_div(&a);
            // Through the taper as `Kernel::residual_grad` does: X = x fx(z), so dx/dX = 1/fx and
            // dx/dz = -x fx'(z) / fx, where the factor is not clamped.
            let factor = |k: f64| {
                let f = k * qu.z / sq.a[2] + 1.0;
                if f >= 0.5 * (1.0 - k.abs()) {
                    (f, k / sq.a[2])
                } else {
                    (0.5 * (1.0 - k.abs()), 0.0)
                }
            };
            let ((fx, sx), (fy, sy)) = (factor(sq.kx), factor(sq.ky));
            let grad = Vector3::new(
                gu.x / fx,
                gu.y / fy,
                gu.z - gu.x * qu.x * sx / fx - gu.y * qu.y * sy / fy,
            );
            SeenSample {
                q,
                grad,
                lid: crate::model::is_lid(&grad),
            }
        })
        .collect()
}

/// The directions of the seen samples: a grid on each face of the unit cube, scaled by the
/// shape's sizes (the parametric angles crowd a box's edges and leave its faces empty, and
/// directions through a cube's faces meet a pen only near its middle; through the box they
/// spread over the faces of a box and the length of a pen alike).
fn seen_directions() -> impl Iterator<Item = Vector3<f64>> {
    let at = |i: usize| -1.0 + (2 * i + 1) as f64 / SEEN_GRID as f64;
    (0..6).flat_map(move |face| {
        (0..SEEN_GRID * SEEN_GRID).map(move |k| {
            let (u, v) = (at(k % SEEN_GRID), at(k / SEEN_GRID));
            match face {
                0 => Vector3::new(1.0, u, v),
                1 => Vector3::new(-1.0, u, v),
                2 => Vector3::new(u, 1.0, v),
                3 => Vector3::new(u, -1.0, v),
                4 => Vector3::new(u, v, 1.0),
                _ => Vector3::new(u, v, -1.0),
            }
        })
    })
}

/// Cells per cube-face side of [`seen_directions`].
pub(super) const SEEN_GRID: usize = 7;
/// How many residuals [`Seen::residuals_of`] gives (one per [`seen_directions`] direction).
pub(super) const SEEN_SAMPLES: usize = 6 * SEEN_GRID * SEEN_GRID;

/// The surface points along [`seen_directions`], directly: the reference [`seen_local`] is
/// tested against.
#[cfg(test)]
pub(super) fn seen_samples(sq: &Superquadric) -> impl Iterator<Item = Vector3<f64>> + '_ {
    let kernel = Kernel::new(sq);
    seen_directions().map(move |c| {
        let d = Vector3::new(c.x * sq.a[0], c.y * sq.a[1], c.z * sq.a[2]).normalize();
        sq.taper(&kernel.untapered_surface_along(&d))
    })
}

/// Fixed parametric angles for the lowest point: the poles, the equator and every 15 degrees.
pub(super) fn surface_samples(sq: &Superquadric) -> impl Iterator<Item = Vector3<f64>> + '_ {
    let spow = |c: f64, e: f64| c.signum() * c.abs().powf(e);
    // The powers of each latitude and longitude once, not once per sample.
    let lat: [(f64, f64); 13] = std::array::from_fn(|i| {
        let eta = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * i as f64 / 12.0;
        (spow(eta.cos(), sq.e1), spow(eta.sin(), sq.e1))
    });
    let lon: [(f64, f64); 24] = std::array::from_fn(|j| {
        let om = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * j as f64 / 24.0;
        (spow(om.cos(), sq.e2), spow(om.sin(), sq.e2))
    });
    lat.into_iter().flat_map(move |(ce, se)| {
        lon.into_iter().map(move |(co, so)| {
            let p = Vector3::new(sq.a[0] * ce * co, sq.a[1] * ce * so, sq.a[2] * se);
            sq.taper(&p)
        })
    })
}

/// Samples along the rays from the viewpoint to the scene points `others` (seen beyond or beside
/// the object), inside the sphere `(centre, radius)`, spaced `radius / 10` (at most 6 mm); at most
/// 300 rays.
pub(super) fn free_space_samples(
    v: &Point3<f64>,
    others: &[Point3<f64>],
    centre: &Vector3<f64>,
    radius: f64,
) -> Vec<Point3<f64>> {
    let c = Point3::from(*centre);
    let rays: Vec<&Point3<f64>> = others
        .iter()
        .filter(|q| {
            let d = *q - v;
            let len = d.norm();
            if len < 1e-9 {
                return false;
            }
            let u = d / len;
            let s = (c - v).dot(&u).clamp(0.0, len);
            ((v + u * s) - c).norm() < radius && (**q - c).norm() > 0.5 * radius.min(0.02)
        })
        .collect();
    let step = (rays.len() / 300).max(1);
    let spacing = (radius / 10.0).min(0.006);
    let mut out = Vec::new();
    for q in rays.into_iter().step_by(step) {
        let d = q - v;
        let len = d.norm();
        let u = d / len;
        let s0 = (c - v).dot(&u);
        let h2 = radius * radius - ((v + u * s0) - c).norm_squared();
        if h2 <= 0.0 {
            continue;
        }
        let h = h2.sqrt();
        // Stop 5 mm short of the seen point: it may touch the object (the table at its foot).
        let (a, b) = ((s0 - h).max(0.0), (s0 + h).min(len - 0.005));
        let mut s = a;
        while s < b {
            out.push(v + u * s);
            s += spacing;
        }
    }
    out
}

/// The free-space samples (along the rays to `free_points`, and just outside the silhouette of
/// `points` where the cloud was segmented) inside the sphere `(centre, radius)`, above `plane`.
pub(super) fn free_space_within(
    points: &[Point3<f64>],
    free_points: &[Point3<f64>],
    centre: &Vector3<f64>,
    radius: f64,
    plane: Option<&crate::cloud::plane::Plane>,
    params: &super::params::LearnParams,
) -> Vec<Point3<f64>> {
    let mut free = match params.viewpoint {
        Some(v) => free_space_samples(&v, free_points, centre, radius),
        None => Vec::new(),
    };
    if let (Some(v), true) = (params.viewpoint, params.silhouette) {
        free.extend(silhouette_samples(&v, points, centre, radius, 0.004));
    }
    if let Some(pl) = plane {
        // Below the table nothing was seen: no free space there.
        free.retain(|p| pl.signed_distance(p) > 0.003);
    }
    free
}

/// The sensor is above the top of an upright shape, yet fewer than 2 % of the points lie on the
/// inner half of its top (a closed top in view shows plenty).
pub(super) fn unseen_top(
    placed: &PlacedSuperquadric,
    points: &[Point3<f64>],
    v: &Point3<f64>,
    up: &Vector3<f64>,
) -> bool {
    let z = placed.pose.rotation * Vector3::z();
    if z.dot(up).abs() < 0.9 {
        return false;
    }
    let a = placed.shape.a;
    let sign = z.dot(up).signum();
    let lv = placed.to_local(v);
    if sign * lv.z < a[2] {
        return false;
    }
    let on_top = points
        .iter()
        .filter(|p| {
            let q = placed.to_local(p);
            sign * q.z > 0.7 * a[2] && (q.x / a[0]).powi(2) + (q.y / a[1]).powi(2) < 0.5
        })
        .count();
    on_top * 50 < points.len()
}

/// Whether an object standing on `plane` is open at the top, judged on its points alone: the
/// sensor is above the object, yet fewer than 2 % of the points lie in the upper 15 % of its
/// height over the inner part of its footprint (the convex hull of all its points, shrunk to
/// 70 % about its centre). A closed top in view shows plenty there; an open container shows its
/// rim at the edge and its inside lower down. `None` when the sensor is not above the object.
/// Unlike [`unseen_top`] this needs no fit: a box seen across a corner can pull the first fit's
/// centre off to the side, so that its own top falls outside the fit's inner half.
pub(super) fn open_top_of_points(points: &[Point3<f64>], plane: &Plane, v: &Point3<f64>) -> Option<bool> {
    let mut h: Vec<f64> = points.iter().map(|p| plane.signed_distance(p)).collect();
    if h.len() < 10 {
        return None;
    }
    h.sort_by(f64::total_cmp);
    let top = h[(h.len() - 1) * 99 / 100];
    if plane.signed_distance(v) < top || top <= 0.0 {
        return None;
    }
    let hull = footprint(points, &plane.normal);
    if hull.len() < 3 {
        return None;
    }
    let n = hull.len() as f64;
    let c = hull.iter().fold((0.0, 0.0), |a, q| (a.0 + q.0 / n, a.1 + q.1 / n));
    let (u, w) = crate::cloud::plane::orthonormal_basis(&plane.normal);
    let band = top - (0.15 * top).max(0.008);
    let on_top = points
        .iter()
        .filter(|p| plane.signed_distance(p) > band)
        .filter(|p| {
            let q = (p.coords.dot(&u), p.coords.dot(&w));
            inside_convex(&hull, (c.0 + (q.0 - c.0) / 0.7, c.1 + (q.1 - c.1) / 0.7))
        })
        .count();
    Some(on_top * 50 < points.len())
}

/// Free-space samples less those in or near `placed` (the inside of an open container, seen
/// through its opening, and its rim).
pub(super) fn drop_rays_through_top(free: &[Point3<f64>], placed: &PlacedSuperquadric) -> Vec<Point3<f64>> {
    free.iter()
        .filter(|p| placed.shape.inside_outside(&placed.to_local(p)) > 1.5)
        .copied()
        .collect()
}

/// The 1-99 % extents of `points` along the local axes of `placed` (m): how much of each full
/// size `2 a` the view shows.
pub fn seen_extent(placed: &PlacedSuperquadric, points: &[Point3<f64>]) -> [f64; 3] {
    let local: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| placed.to_local(p))
        .filter(|q| q.iter().all(|v| v.is_finite()))
        .collect();
    if local.is_empty() {
        return [0.0; 3];
    }
    [0, 1, 2].map(|k| {
        let mut v: Vec<f64> = local.iter().map(|q| q[k]).collect();
        v.sort_by(f64::total_cmp);
        let at = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        at(0.99) - at(0.01)
    })
}

/// The convex hull (counter-clockwise) of the points projected on the plane across `normal`, in
/// the basis of [`crate::cloud::plane::orthonormal_basis`].
pub fn footprint(points: &[Point3<f64>], normal: &Vector3<f64>) -> Vec<(f64, f64)> {
    let (u, v) = crate::cloud::plane::orthonormal_basis(normal);
    hull2d(points.iter().map(|p| (p.coords.dot(&u), p.coords.dot(&v))).collect())
}

/// A point set's outline seen along a normal (its [`footprint`]), to ask which points lie within
/// it.
pub struct Outline {
    hull: Vec<(f64, f64)>,
    u: Vector3<f64>,
    v: Vector3<f64>,
}

impl Outline {
    pub fn of(points: &[Point3<f64>], normal: &Vector3<f64>) -> Outline {
        let (u, v) = crate::cloud::plane::orthonormal_basis(normal);
        Outline {
            hull: footprint(points, normal),
            u,
            v,
        }
    }

    /// Whether `p`, seen along the normal, lies within the outline.
    pub fn holds(&self, p: &Point3<f64>) -> bool {
        inside_convex(&self.hull, (p.coords.dot(&self.u), p.coords.dot(&self.v)))
    }
}

/// The convex hull of 2-D points, counter-clockwise (Andrew's monotone chain).
pub fn hull2d(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    let mut hull: Vec<(f64, f64)> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Free-space samples along rays just outside the object's silhouette as the sensor saw it: the
/// convex hull of the points in the image (perspective coordinates about the view axis), grown
/// by `margin` metres at the object's range. The sensor saw the whole silhouette, so nothing of
/// the object lies on these rays, even when the cloud holds nothing behind them (a cloud
/// segmented beforehand).
pub(super) fn silhouette_samples(
    v: &Point3<f64>,
    object: &[Point3<f64>],
    centroid: &Vector3<f64>,
    radius: f64,
    margin: f64,
) -> Vec<Point3<f64>> {
    let Some(w) = (centroid - v.coords).try_normalize(1e-9) else {
        return Vec::new();
    };
    let (u1, u2) = crate::cloud::plane::orthonormal_basis(&w);
    let depth = (centroid - v.coords).norm();
    let proj: Vec<(f64, f64)> = object
        .iter()
        .filter_map(|p| {
            let d = p - v;
            let z = d.dot(&w);
            (z > 1e-6).then(|| (d.dot(&u1) / z, d.dot(&u2) / z))
        })
        .collect();
    let hull = hull2d(proj);
    if hull.len() < 3 {
        return Vec::new();
    }
    let n = hull.len() as f64;
    let hc = hull.iter().fold((0.0, 0.0), |a, h| (a.0 + h.0 / n, a.1 + h.1 / n));
    let grow = margin / depth;
    let grown: Vec<(f64, f64)> = hull
        .iter()
        .map(|h| {
            let (dx, dy) = (h.0 - hc.0, h.1 - hc.1);
            let l = (dx * dx + dy * dy).sqrt().max(1e-12);
            (h.0 + grow * dx / l, h.1 + grow * dy / l)
        })
        .collect();
    let step = 0.004 / depth;
    let spacing = (radius / 10.0).min(0.006);
    let mut out = Vec::new();
    for i in 0..grown.len() {
        let (a, b) = (grown[i], grown[(i + 1) % grown.len()]);
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        let k = (len / step).ceil().max(1.0) as usize;
        for j in 0..k {
            let t = j as f64 / k as f64;
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            let dir = (w + u1 * x + u2 * y).normalize();
            let s0 = (centroid - v.coords).dot(&dir);
            let mut s = s0 - radius;
            while s < s0 + radius {
                if s > 0.0 {
                    out.push(v + dir * s);
                }
                s += spacing;
            }
        }
    }
    out
}

/// Whether a point lies inside a counter-clockwise convex polygon.
pub fn inside_convex(hull: &[(f64, f64)], p: (f64, f64)) -> bool {
    if hull.len() < 3 {
        return false;
    }
    (0..hull.len()).all(|i| {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seen_samples_from_the_exponents_are_the_direct_ones() {
        let shapes = [
            Superquadric::new([0.04, 0.03, 0.05], 0.3, 0.7, 0.25, -0.15).unwrap(),
            Superquadric::new([0.005, 0.005, 0.07], 0.1, 1.0, 0.0, 0.0).unwrap(),
            Superquadric::new([0.06, 0.06, 0.02], 1.7, 2.0, -0.6, 0.9).unwrap(),
        ];
        for sq in shapes {
            let kernel = Kernel::new(&sq);
            let local = seen_local(&SeenUnit::new(sq.e1, sq.e2), &sq);
            let direct: Vec<Vector3<f64>> = seen_samples(&sq).collect();
            assert_eq!(local.len(), SEEN_SAMPLES);
            for (l, d) in local.iter().zip(&direct) {
                assert!((l.q - d).norm() < 1e-12 * sq.max_size(), "{sq}: {:?} vs {d:?}", l.q);
                let g = kernel.residual_grad(d).grad;
                let cos = l.grad.normalize().dot(&g.normalize());
                assert!(cos > 1.0 - 1e-9, "{sq} at {d:?}: normal {:?} vs {g:?}", l.grad);
                assert_eq!(l.lid, crate::model::is_lid(&g));
            }
        }
    }
}
