//! Joint refinement of a compound object's pose: all parts move together as the rigid model
//! says, fitted by Levenberg-Marquardt to the points near any part.
//!
//! The paper votes on the parts' independent fits; their connection errors A and D rank the
//! combinations. Once a combination is chosen, fitting the whole object at once uses every
//! visible point of every part for all six parameters: a cup's handle fixes the spin its body
//! cannot, and a half-hidden handle no longer drags its own fit off.

use super::fit::{LANES, Rows, measure_of_fit, normal_sums, squared_residuals, symmetric};
use super::space::SearchSpace;
use crate::geometry::{PlacedKernel, PlacedSuperquadric, ResidualGrad, lanes_of};
use crate::model::Model;
use crate::numeric::lanes::{Lanes, widened};
use crate::numeric::{LeastSquares, LmSettings, minimize};
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, UnitQuaternion, Vector3, Vector6};

widened! {
/// Points near the placed model, each in the list of the part whose surface it is nearest.
fn gather(space: &SearchSpace<'_>, parts: &[PlacedSuperquadric], band: f64) -> Vec<Vec<Point3<f64>>> {
    let centre = parts
        .iter()
        .fold(Vector3::zeros(), |a, p| a + p.pose.translation.vector)
        / parts.len() as f64;
    let reach = parts
        .iter()
        .map(|p| (p.pose.translation.vector - centre).norm() + p.shape.bounding_radius())
        .fold(0.0, f64::max)
        + band;
    let kernels: Vec<PlacedKernel> = parts.iter().map(PlacedKernel::new).collect();
    // Only points within `band` of some part's box can be within `band` of its surface.
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for (p, k) in parts.iter().zip(&kernels) {
        let r = k.frame_reach(band);
        lo = lo.inf(&(p.pose.translation.vector - r));
        hi = hi.sup(&(p.pose.translation.vector + r));
    }
    let half = (hi - centre).sup(&(centre - lo));
    let mut near = Vec::new();
    space
        .grid
        .for_each_within_box(space.points, &Point3::from(centre), reach, &half, |i| {
            let p = &space.points[i];
            if kernels.iter().any(|k| k.in_box(p, band)) {
                near.push(*p)
            }
        });
    let mut out = vec![Vec::new(); parts.len()];
    // Each point's surface distance to every part, four points at a time.
    let mut d = vec![[0.0; LANES]; parts.len()];
    for group in near.chunks(LANES) {
        let padded: [Point3<f64>; LANES] = std::array::from_fn(|i| group[i % group.len()]);
        let p = lanes_of::<LANES>(&padded);
        for (k, part) in kernels.iter().enumerate() {
            let (r, g) = part.kernel.residual_grad_lanes(part.to_local_lanes(p));
            for (i, dk) in d[k].iter_mut().enumerate() {
                *dk = PlacedSuperquadric::distance_from(&ResidualGrad {
                    residual: r.0[i],
                    grad: Vector3::new(g[0].0[i], g[1].0[i], g[2].0[i]),
                });
            }
        }
        for (i, p) in group.iter().enumerate() {
            let mut best = (f64::INFINITY, usize::MAX);
            for (k, dk) in d.iter().enumerate() {
                if dk[i].abs() < best.0.abs() {
                    best = (dk[i], k);
                }
            }
            // A point inside one part but on another's surface belongs to the other: a handle's
            // root sits inside the body.
            if best.0.abs() < band && d.iter().all(|dk| dk[i] > -band) {
                out[best.1].push(*p);
            }
        }
    }
    out
}
}

fn place(model: &Model, pose: &Isometry3<f64>) -> Vec<PlacedSuperquadric> {
    model.placed_parts(pose)
}

/// `sum r^2` over the parts' points.
fn cost(model: &Model, pose: &Isometry3<f64>, by_part: &[Vec<Point3<f64>>]) -> f64 {
    place(model, pose)
        .iter()
        .zip(by_part)
        .map(|(part, pts)| squared_residuals(&PlacedKernel::new(part), pts))
        .sum()
}

/// A fit in the final band that moves the pose less than this (m, rad) ends the refinement.
const STILL_M: f64 = 1e-5;
const STILL_RAD: f64 = 1e-4;

/// Refine the object pose with the parts held rigidly, over `rounds` rounds of point gathering
/// with a band shrinking from `start_band` to `final_band`. Returns the pose and the M over the
/// final points.
pub fn refine_object(
    space: &SearchSpace<'_>,
    model: &Model,
    start: &Isometry3<f64>,
    start_band: f64,
    final_band: f64,
    iterations: usize,
) -> (Isometry3<f64>, f64) {
    let mut pose = *start;
    let mut band = start_band.max(final_band);
    let mut m = f64::INFINITY;
    for _ in 0..6 {
        let by_part = gather(space, &place(model, &pose), band);
        let n: usize = by_part.iter().map(Vec::len).sum();
        if n < 8 {
            break;
        }
        // A round in a band wider than the final one only brings the pose near enough for the
        // next, narrower gathering: it stops at a 0.1 % improvement, as a single part's coarse
        // rounds do (`refine::refine_coarse`). The final band's rounds converge fully.
        let tol = if band > final_band { 1e-3 } else { 1e-6 };
        let (fitted, fitted_cost) = fit_object(model, &pose, &by_part, iterations, tol);
        // A pose that hardly moved would gather the same points again and stay where it is.
        let still = (fitted.translation.vector - pose.translation.vector).norm() < STILL_M
            && fitted.rotation.angle_to(&pose.rotation) < STILL_RAD;
        pose = fitted;
        let new_m = (fitted_cost / n as f64).sqrt();
        let done = band <= final_band && (new_m >= 0.999 * m || still);
        m = new_m;
        if done {
            break;
        }
        band = (0.5 * band).max(final_band);
    }
    if !m.is_finite() {
        let by_part = gather(space, &place(model, &pose), final_band);
        let parts = place(model, &pose);
        let p: Vec<Point3<f64>> = by_part.into_iter().flatten().collect();
        m = parts.first().map_or(f64::INFINITY, |q| measure_of_fit(q, &p));
    }
    (pose, m)
}

/// LM on the object pose: translation in the frame, rotation vector in the object frame. Returns
/// the pose and its cost `sum r^2`.
fn fit_object(
    model: &Model,
    start: &Isometry3<f64>,
    by_part: &[Vec<Point3<f64>>],
    iterations: usize,
    tol: f64,
) -> (Isometry3<f64>, f64) {
    let found = minimize(
        &RigidFit { model, by_part },
        *start,
        &LmSettings::attempts(iterations, tol),
    );
    (found.x, found.cost)
}

/// The pose of an object whose parts are held rigidly, each point on the part it was gathered
/// for.
struct RigidFit<'a> {
    model: &'a Model,
    by_part: &'a [Vec<Point3<f64>>],
}

impl LeastSquares<6> for RigidFit<'_> {
    type Params = Isometry3<f64>;
    // A candidate's cost alone: the normal equations only for the pose a step is taken from.
    type Evaluation = ();

    fn evaluate(&self, pose: &Isometry3<f64>) -> (f64, ()) {
        (cost(self.model, pose, self.by_part), ())
    }

    fn linearize(&self, pose: &Isometry3<f64>, _: &()) -> (Matrix6<f64>, Vector6<f64>) {
        let parts = place(self.model, pose);
        let rot_inv = pose.rotation.inverse().to_rotation_matrix().into_inner();
        let mut upper = [0.0; 21];
        let mut g = [0.0; 6];
        for (k, pts) in self.by_part.iter().enumerate() {
            let rows = RigidRows {
                kernel: PlacedKernel::new(&parts[k]),
                rot_inv,
                m_t: self.model.parts[k].pose_in_object.translation.vector,
                m_r: self.model.parts[k]
                    .pose_in_object
                    .rotation
                    .to_rotation_matrix()
                    .into_inner(),
            };
            let (u, gk, _) = rigid_sums(pts, &rows);
            for (a, b) in upper.iter_mut().zip(u) {
                *a += b;
            }
            for (a, b) in g.iter_mut().zip(gk) {
                *a += b;
            }
        }
        (symmetric(&upper), Vector6::from(g))
    }

    fn step(&self, pose: &Isometry3<f64>, delta: &Vector6<f64>) -> Isometry3<f64> {
        let t = pose.translation.vector + Vector3::new(delta[0], delta[1], delta[2]);
        let r = pose.rotation * UnitQuaternion::from_scaled_axis(Vector3::new(delta[3], delta[4], delta[5]));
        Isometry3::from_parts(t.into(), r)
    }
}

/// The object-pose rows of one part's points.
struct RigidRows {
    kernel: PlacedKernel,
    /// The object's rotation, inverted.
    rot_inv: Matrix3<f64>,
    /// The part's pose in the object.
    m_t: Vector3<f64>,
    m_r: Matrix3<f64>,
}

impl Rows for RigidRows {
    #[inline(always)]
    fn rows(&self, p: [Lanes<LANES>; 3]) -> (Lanes<LANES>, [Lanes<LANES>; 6]) {
        let (r, j) = self.kernel.residual_pose_jacobian_lanes(p);
        // Part perturbation from object perturbation: dt_part = dt - R [m_t]x w and
        // w_part = M_R^T w, so dr/dw = -(R^T j_t) x m_t + M_R j_w.
        let (jt, jw) = ([j[0], j[1], j[2]], [j[3], j[4], j[5]]);
        let mul = |m: &Matrix3<f64>, v: &[Lanes<LANES>; 3]| -> [Lanes<LANES>; 3] {
            std::array::from_fn(|i| v[0] * m[(i, 0)] + v[1] * m[(i, 1)] + v[2] * m[(i, 2)])
        };
        let a = mul(&self.rot_inv, &jt);
        let b = mul(&self.m_r, &jw);
        let t = &self.m_t;
        let dw = [
            b[0] - (a[1] * t.z - a[2] * t.y),
            b[1] - (a[2] * t.x - a[0] * t.z),
            b[2] - (a[0] * t.y - a[1] * t.x),
        ];
        (r, [jt[0], jt[1], jt[2], dw[0], dw[1], dw[2]])
    }
}

widened! {
fn rigid_sums(points: &[Point3<f64>], rows: &RigidRows) -> ([f64; 21], [f64; 6], f64) {
    normal_sums(points, rows)
}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Model;
    use std::path::Path;

    /// The object-pose Jacobian agrees with finite differences of the part residuals.
    #[test]
    fn object_jacobian_matches_finite_differences() {
        let model = Model::load("cup", &Path::new(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap();
        let pose = Isometry3::new(Vector3::new(0.9, 0.1, 0.77), Vector3::new(0.2, -0.1, 0.7));
        let parts = place(&model, &pose);
        let p = Point3::new(0.93, 0.12, 0.80);
        for k in 0..2 {
            let (_, j) = parts[k].residual_pose_jacobian(&p);
            let m_t = model.parts[k].pose_in_object.translation.vector;
            let m_r = model.parts[k].pose_in_object.rotation;
            let jt = Vector3::new(j[0], j[1], j[2]);
            let jw = Vector3::new(j[3], j[4], j[5]);
            let dw = -(pose.rotation.inverse() * jt).cross(&m_t) + m_r * jw;
            let analytic = [jt.x, jt.y, jt.z, dw.x, dw.y, dw.z];
            for d in 0..6 {
                let h = 1e-7;
                let mut delta = [0.0; 6];
                delta[d] = h;
                let perturb = |delta: &[f64; 6]| {
                    let t = pose.translation.vector + Vector3::new(delta[0], delta[1], delta[2]);
                    let r =
                        pose.rotation * UnitQuaternion::from_scaled_axis(Vector3::new(delta[3], delta[4], delta[5]));
                    place(&model, &Isometry3::from_parts(t.into(), r))[k].residual(&p)
                };
                let plus = perturb(&delta);
                delta[d] = -h;
                let minus = perturb(&delta);
                let fd = (plus - minus) / (2.0 * h);
                assert!(
                    (fd - analytic[d]).abs() < 1e-4 * analytic.iter().fold(1.0f64, |a, v| a.max(v.abs())),
                    "part {k} param {d}: {fd} vs {}",
                    analytic[d]
                );
            }
        }
    }
}
