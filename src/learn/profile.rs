//! An open container standing upright, learned from its outer wall's profile.
//!
//! Seen from above, a mug or a bowl shows its outer wall on the side that faces the sensor and
//! its inner wall and bottom through the opening. A closed superquadric fitted to all of them
//! puts its surface between the two walls and pulls its top down towards the inner bottom, so
//! the model comes out a wall's thickness or more too small. The outer wall alone says what the
//! detector needs: its radius at each height, about one vertical axis. This finds the axis from
//! the rim (seen all round from above), measures the near wall's radius in height slices, fills
//! the slices where the near wall is hidden from the far wall's inside plus the wall's
//! thickness, and fits the tapered superquadric's section radius to that profile, which for a
//! fixed `e1` is linear in `a` and `a k`.

use super::state::{State, TAPER_BOUND};
use crate::cloud::plane::{Plane, orthonormal_basis};
use crate::geometry::{EPSILON_MIN, Superquadric};
use crate::numeric::{huber_weight, median, quantile};
use nalgebra::{Matrix2, Point3, Rotation3, UnitQuaternion, Vector2};

/// Height of a profile slice (m).
const SLICE: f64 = 0.01;
/// A slice needs this many outer-wall points to measure its radius.
const MIN_SLICE_POINTS: usize = 12;
/// Half the angle about the view direction (from the axis) within which the wall faces the
/// sensor well enough to be measured: beyond it the rays graze the wall and the sensor's edge
/// noise grows.
const CONE_HALF_ANGLE_DEG: f64 = 60.0;
/// The rim: the points this close below the wall's top (m).
const RIM_BAND: f64 = 0.006;
/// The thickest wall taken from the difference of the near and far sides (m).
const MAX_WALL: f64 = 0.01;
/// Huber threshold of the wall fit (m): a few sigmas of a depth camera's noise at a metre.
const WALL_DELTA: f64 = 0.002;
/// The outer wall must fit its circles to this median absolute residual (m), or the object is
/// not a body of revolution and the general fit decides.
const MAX_WALL_MEDIAN: f64 = 0.003;

/// The measured profile: the axis (in the plane's basis) and (height, radius, weight) per slice.
#[derive(Debug, Clone)]
pub(super) struct Profile {
    pub(super) centre: Vector2<f64>,
    pub(super) slices: Vec<(f64, f64, f64)>,
    /// The top of the wall above the plane (m).
    pub(super) top: f64,
}

/// One side of the wall: the points of each slice within the cone about `towards` (from the
/// centre), out at the slice's wall.
struct Side {
    /// (slice, height, flat position) of the wall's points.
    points: Vec<(usize, f64, Vector2<f64>)>,
    /// The wall's radius in each slice (NaN where too few points show it).
    radii: Vec<f64>,
}

impl Side {
    /// The points of `pts` within the cone about the direction `towards`, sorted into slices; in
    /// each slice those out at the wall (beyond 0.8 of its 90th-percentile radius: nearer the
    /// axis lies the inside bottom seen through the opening), their median radius the slice's.
    fn gather(pts: &[(f64, Vector2<f64>)], centre: &Vector2<f64>, towards: &Vector2<f64>, slices: usize) -> Side {
        let cos_cone = CONE_HALF_ANGLE_DEG.to_radians().cos();
        let slice_of = |h: f64| ((h / SLICE).floor().max(0.0) as usize).min(slices - 1);
        let mut by_slice: Vec<Vec<f64>> = vec![Vec::new(); slices];
        let mut points = Vec::new();
        for (h, q) in pts {
            let d = q - centre;
            let r = d.norm();
            if *h >= 0.0 && r > 1e-9 && d.dot(towards) >= cos_cone * r {
                by_slice[slice_of(*h)].push(r);
                points.push((slice_of(*h), *h, *q));
            }
        }
        let radii: Vec<f64> = by_slice
            .iter_mut()
            .map(|rs| {
                if rs.len() < MIN_SLICE_POINTS {
                    return f64::NAN;
                }
                let outer = quantile(rs, 0.9).unwrap_or(f64::NAN);
                let mut wall: Vec<f64> = rs.iter().copied().filter(|r| *r > 0.8 * outer).collect();
                if wall.len() < MIN_SLICE_POINTS {
                    return f64::NAN;
                }
                median(&mut wall).unwrap_or(f64::NAN)
            })
            .collect();
        points.retain(|(k, _, q)| radii[*k].is_finite() && (q - centre).norm() > 0.8 * radii[*k]);
        Side { points, radii }
    }

    /// (mean height, radius, points) of the slices that show the wall.
    fn slices(&self) -> Vec<(f64, f64, usize)> {
        let mut counts = vec![0usize; self.radii.len()];
        let mut sum_h = vec![0.0; self.radii.len()];
        for (k, h, _) in &self.points {
            counts[*k] += 1;
            sum_h[*k] += *h;
        }
        (0..self.radii.len())
            .filter(|&k| counts[k] >= MIN_SLICE_POINTS)
            .map(|k| (sum_h[k] / counts[k] as f64, self.radii[k], counts[k]))
            .collect()
    }
}

/// The outer wall's profile of an upright container standing on `plane`, seen from
/// `viewpoint`; `None` when fewer than three slices show enough of it, or it is not round.
///
/// The axis is the centre of the rim's circle, and each slice's radius the median distance from
/// it of the near (outer) wall's points.
/// Where the near wall is hidden (a bowl widening upwards hides its foot under its rim) the far
/// wall's inside, seen through the opening, stands in for it: a vessel's wall is about as thick
/// everywhere, so there the outer radius is the inner one plus the difference the two show where
/// both are seen.
pub(super) fn measure(points: &[Point3<f64>], plane: &Plane, viewpoint: &Point3<f64>) -> Option<Profile> {
    let (u, w) = orthonormal_basis(&plane.normal);
    let flat = |p: &Point3<f64>| Vector2::new(p.coords.dot(&u), p.coords.dot(&w));
    let pts: Vec<(f64, Vector2<f64>)> = points.iter().map(|p| (plane.signed_distance(p), flat(p))).collect();
    let mut heights: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let top = quantile(&mut heights, 0.99)?;
    if !(top > 3.0 * SLICE) {
        return None;
    }
    let eye = flat(viewpoint);
    let slices = (top / SLICE).ceil() as usize;
    // The axis goes through the centre of the rim: seen from above, the sensor sees it on the
    // near side and across the opening on the far side, a circle on both sides of its centre.
    // (The near wall's arc alone fixes the centre's depth only through its curvature, a valley
    // along which the radius and the depth trade millimetres for millimetres, and its grazing
    // ends, which the sensor pushes back, tilt it towards larger radii.)
    let rim: Vec<Vector2<f64>> = pts.iter().filter(|p| p.0 > top - RIM_BAND).map(|p| p.1).collect();
    let centre = circle_fit(&rim)?;
    let view = (eye - centre).try_normalize(1e-9)?;
    let near = Side::gather(&pts, &centre, &view, slices);
    let mut residuals: Vec<f64> = near
        .points
        .iter()
        .map(|(k, _, q)| ((q - centre).norm() - near.radii[*k]).abs())
        .collect();
    let median_residual = median(&mut residuals)?;
    let outer = near.slices();
    let inner = Side::gather(&pts, &centre, &(-view), slices).slices();
    // The wall's thickness where both sides are seen (the far side's inside lies nearer the axis).
    let mut both: Vec<f64> = outer
        .iter()
        .filter_map(|o| {
            inner
                .iter()
                .find(|i| (i.0 - o.0).abs() < 0.5 * SLICE)
                .map(|i| o.1 - i.1)
        })
        .collect();
    let thickness = median(&mut both).map(|t| t.clamp(0.0, MAX_WALL));
    let mut profile: Vec<(f64, f64, f64)> = outer.iter().map(|&(h, r, n)| (h, r, n as f64)).collect();
    if let Some(t) = thickness {
        let lowest_outer = outer.iter().map(|o| o.0).fold(f64::INFINITY, f64::min);
        // Below the lowest slice of the near wall, with half the weight: an estimate.
        profile.extend(
            inner
                .iter()
                .filter(|i| i.0 < lowest_outer - 0.5 * SLICE)
                .map(|&(h, r, n)| (h, r + t, 0.5 * n as f64)),
        );
    }
    tracing::debug!(
        "outer wall profile: top {:.1} mm, median residual {:.2} mm, wall {:?} mm, slices (h, r, n) {:?}",
        top * 1e3,
        median_residual * 1e3,
        thickness.map(|t| (t * 1e4).round() / 10.0),
        profile
            .iter()
            .map(|s| ((s.0 * 1e4).round() / 10.0, (s.1 * 1e4).round() / 10.0, s.2))
            .collect::<Vec<_>>()
    );
    (outer.len() >= 3 && median_residual <= MAX_WALL_MEDIAN).then_some(Profile {
        centre,
        slices: profile,
        top,
    })
}

/// The centre of the circle through `points`: the algebraic fit, then Gauss-Newton on the
/// Huber-weighted distances (the algebraic fit weights points by their radius and is pulled by
/// strays).
pub(super) fn circle_fit(points: &[Vector2<f64>]) -> Option<Vector2<f64>> {
    let mut centre = kasa_centre(points)?;
    for _ in 0..20 {
        let mut d: Vec<f64> = points.iter().map(|p| (p - centre).norm()).collect();
        let radius = median(&mut d)?;
        let (mut jtj, mut jtr) = (nalgebra::Matrix3::zeros(), nalgebra::Vector3::zeros());
        for p in points {
            let d = p - centre;
            let r = d.norm();
            if r < 1e-9 {
                continue;
            }
            let res = r - radius;
            let wt = huber_weight(res, WALL_DELTA);
            let j = nalgebra::Vector3::new(-d.x / r, -d.y / r, -1.0);
            jtj += wt * j * j.transpose();
            jtr += wt * j * res;
        }
        let step = jtj.try_inverse()? * -jtr;
        centre += Vector2::new(step.x, step.y);
        if step.x.hypot(step.y) < 1e-6 {
            break;
        }
    }
    Some(centre)
}

/// The centre of the algebraic (Kasa) circle fit: least squares of `x^2 + y^2 = 2 c.x + 2 c.y
/// + b` over the points, relative to their mean for conditioning.
fn kasa_centre(points: &[Vector2<f64>]) -> Option<Vector2<f64>> {
    if points.len() < 3 {
        return None;
    }
    let mean = points.iter().fold(Vector2::zeros(), |s, p| s + p) / points.len() as f64;
    let (mut m, mut b) = (nalgebra::Matrix3::zeros(), nalgebra::Vector3::zeros());
    for p in points {
        let d = p - mean;
        let row = nalgebra::Vector3::new(2.0 * d.x, 2.0 * d.y, 1.0);
        m += row * row.transpose();
        b += row * d.norm_squared();
    }
    let sol = m.try_inverse()? * b;
    Some(mean + Vector2::new(sol.x, sol.y))
}

/// The section radius of a tapered superquadric of revolution at height `h` above its base
/// (the plane it stands on), per unit `a`, as the pair (untapered, taper's factor) that
/// `a (g.0 + k g.1)` combines: linear in `a` and `a k`.
fn section_basis(h: f64, a3: f64, e1: f64) -> Vector2<f64> {
    let z = (h - a3) / a3;
    let t = z.abs().min(1.0);
    let g = (1.0 - t.powf(2.0 / e1)).max(0.0).powf(0.5 * e1);
    Vector2::new(g, g * z)
}

/// Where (height above the base) the wall of an open part ends: the lid of an open part begins
/// where its outward normal turns up past [`crate::model::LID_NORMAL_Z`], which on the section's
/// outline `r(h)` is where it falls more steeply than `dr/dh = -z / sqrt(1 - z^2)`.
fn wall_top(sq: &Superquadric) -> f64 {
    let nz = crate::model::LID_NORMAL_Z;
    let steepest = -nz / (1.0 - nz * nz).sqrt();
    let a3 = sq.a[2];
    let r = |h: f64| {
        let g = section_basis(h, a3, sq.e1);
        sq.a[0] * (g.x + sq.kx * g.y)
    };
    // Down from the top in steps of a thousandth of the height, to the first slope less steep.
    let dh = 2.0 * a3 / 1000.0;
    let mut h = 2.0 * a3 - dh;
    while h > a3 {
        if (r(h) - r(h - dh)) / dh > steepest {
            return h;
        }
        h -= dh;
    }
    a3
}

/// The tapered superquadric of revolution standing on the plane whose section radius best
/// matches the profile (least squares over the slices, each weighted by the square root of its
/// points) and whose wall, as the detector reads an open part, ends at the rim: the half-height
/// and `e1` (of the form `2/n`) by search, `a` and `a k` by linear least squares. A rounded top (a bowl's) closes
/// above its rim, so the half-height runs from half the rim's height to 5 % more.
pub(super) fn fit(profile: &Profile) -> Option<(Superquadric, f64)> {
    let mut best: Option<(Superquadric, f64)> = None;
    let heaviest = profile.slices.iter().map(|s| s.2.sqrt()).fold(0.0, f64::max);
    for j in 0..=5 {
        let a3 = 0.5 * profile.top * (1.0 + 0.01 * j as f64);
        // e1 = 2/n: the shapes the detector evaluates without logarithms (about twice as
        // fast). Between neighbours the profile's RMS changes by a fraction of a millimetre.
        for n in 2..=(2.0 / EPSILON_MIN).round() as i32 {
            let e1 = 2.0 / n as f64;
            let (mut m, mut b, mut wsum) = (Matrix2::zeros(), Vector2::zeros(), 0.0);
            for &(h, r, n) in &profile.slices {
                let wt = n.sqrt();
                let x = section_basis(h, a3, e1);
                m += wt * x * x.transpose();
                b += wt * x * r;
                wsum += wt;
            }
            let Some(sol) = m.try_inverse().map(|inv| inv * b) else {
                continue;
            };
            let a = sol.x;
            if !(a > 0.0) {
                continue;
            }
            let k = (sol.y / a).clamp(-TAPER_BOUND, TAPER_BOUND);
            let sq = Superquadric {
                a: [a, a, a3],
                e1,
                e2: 1.0,
                kx: k,
                ky: k,
            };
            let sse: f64 = profile
                .slices
                .iter()
                .map(|&(h, r, n)| {
                    let x = section_basis(h, a3, e1);
                    n.sqrt() * (a * (x.x + k * x.y) - r).powi(2)
                })
                .sum::<f64>()
                + heaviest * (wall_top(&sq) - profile.top).powi(2);
            let rms = (sse / (wsum + heaviest)).sqrt();
            if best.as_ref().is_none_or(|(_, e)| rms < *e) {
                best = Some((sq, rms));
            }
        }
    }
    best
}

/// The fit's state of `shape` standing on `plane` about the profile's axis.
pub(super) fn state(profile: &Profile, shape: &Superquadric, plane: &Plane) -> State {
    let (u, w) = orthonormal_basis(&plane.normal);
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[u, w, plane.normal]));
    let t = u * profile.centre.x + w * profile.centre.y + plane.normal * (shape.a[2] - plane.d);
    State {
        ln_a: shape.a.map(f64::ln),
        e: [shape.e1, shape.e2],
        k: [shape.kx, shape.ky],
        rot,
        t,
        rev: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A tapered bowl seen from one side and above: the near half of its outer wall (2 mm
    /// rings), the far half of its inner wall and its inside bottom. The axis and the shape come
    /// back.
    #[test]
    fn a_bowl_profile_comes_back() {
        let (a, a3, e1, k) = (0.06, 0.045, 0.3, 0.35);
        let radius = |h: f64| {
            let z = h - a3;
            let t: f64 = (z / a3).abs();
            a * (1.0 + k * z / a3) * (1.0 - t.powf(2.0 / e1)).max(0.0).powf(0.5 * e1)
        };
        let plane = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        let axis = Vector2::new(0.1, -0.05);
        let ring = |points: &mut Vec<Point3<f64>>, h: f64, r: f64, from: f64| {
            for k in 0..60 {
                let phi = std::f64::consts::PI * (from + k as f64 / 60.0);
                points.push(Point3::new(axis.x + r * phi.cos(), axis.y + r * phi.sin(), h));
            }
        };
        let mut points = Vec::new();
        // The near wall faces -y, where the sensor is; the far wall's inside, 3 mm in, shows
        // above 30 mm; the inside bottom through the opening.
        let mut h = 0.001;
        while h < 0.09 {
            ring(&mut points, h, radius(h), 1.0);
            if h > 0.03 {
                ring(&mut points, h, radius(h) - 0.003, 0.0);
            }
            h += 0.002;
        }
        for k in 0..200 {
            let r = 0.03 * (k % 10) as f64 / 10.0;
            let phi = k as f64 * 0.7;
            points.push(Point3::new(axis.x + r * phi.cos(), axis.y + r * phi.sin(), 0.006));
        }
        let eye = Point3::new(0.1, -1.0, 0.6);
        let profile = measure(&points, &plane, &eye).expect("a profile");
        // The centre is in the plane's basis.
        let (u, w) = orthonormal_basis(&plane.normal);
        let expected = Vector2::new(u.x * axis.x + u.y * axis.y, w.x * axis.x + w.y * axis.y);
        assert!((profile.centre - expected).norm() < 0.002, "axis {:?}", profile.centre);
        let (sq, rms) = fit(&profile).expect("a fit");
        assert!(rms < 0.002, "rms {rms}");
        for h in [0.02, 0.045, 0.07] {
            let z = h - sq.a[2];
            let t = (z / sq.a[2]).abs();
            let r = sq.a[0] * (1.0 + sq.kx * z / sq.a[2]) * (1.0 - t.powf(2.0 / sq.e1)).powf(0.5 * sq.e1);
            assert!((r - radius(h)).abs() < 0.003, "at {h}: {r} for {} ({sq})", radius(h));
        }
    }

    /// A box's walls are not circles: no profile.
    #[test]
    fn a_box_has_no_profile() {
        let plane = Plane {
            normal: Vector3::z(),
            d: 0.0,
        };
        let mut points = Vec::new();
        let mut h = 0.001;
        while h < 0.08 {
            for k in 0..=40 {
                let s = -0.05 + 0.1 * k as f64 / 40.0;
                // The near face and a side face of a 10 cm box, and its far face's inside.
                points.push(Point3::new(s, -0.05, h));
                points.push(Point3::new(-0.05, s, h));
                points.push(Point3::new(s, 0.047, h));
            }
            h += 0.002;
        }
        let eye = Point3::new(0.3, -1.0, 0.6);
        assert!(measure(&points, &plane, &eye).is_none());
    }
}
