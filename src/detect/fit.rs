//! Levenberg-Marquardt fit of a superquadric's pose (size, shape and taper fixed) to points,
//! minimising the paper's eq. (2), `sum (F^e1 - 1)^2`.
//!
//! The normal equations are a 6x6 system built in one pass over the points (no n x 6 Jacobian
//! is stored), the pose is updated on the manifold (a local rotation vector, see
//! `PlacedSuperquadric::residual_pose_jacobian`), and a body of revolution simply drops its
//! unobservable spin. The solver is [`crate::numeric::lm`].

use crate::geometry::{PlacedKernel, PlacedSuperquadric, lanes_of};
use crate::numeric::lanes::{Lanes, widened};
use crate::numeric::{LeastSquares, LmSettings, minimize};
use nalgebra::{Matrix6, Point3, Vector6};

/// Result of a pose fit.
#[derive(Debug, Clone, Copy)]
pub struct Fit {
    pub placed: PlacedSuperquadric,
    /// The paper's measure of fit M (eq. 3): the RMS of `F^e1 - 1`.
    pub m: f64,
    pub iterations: usize,
}

/// The paper's M (eq. 3) of a placed superquadric over points.
pub fn measure_of_fit(placed: &PlacedSuperquadric, points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return f64::INFINITY;
    }
    (squared_residuals(&PlacedKernel::new(placed), points) / points.len() as f64).sqrt()
}

widened! {
/// `sum (F^e1 - 1)^2` of frame points, four at a time.
pub(super) fn squared_residuals(kernel: &PlacedKernel, points: &[Point3<f64>]) -> f64 {
    let mut sum = Lanes::<LANES>::splat(0.0);
    let chunks = points.chunks_exact(LANES);
    let rest = chunks.remainder();
    for c in chunks {
        let (r, _) = kernel.kernel.residual_grad_lanes(kernel.to_local_lanes(lanes_of::<LANES>(c)));
        sum = sum + r * r;
    }
    let mut sum = sum.sum();
    if !rest.is_empty() {
        let padded: [Point3<f64>; LANES] = std::array::from_fn(|i| rest[i % rest.len()]);
        let (r, _) = kernel.kernel.residual_grad_lanes(kernel.to_local_lanes(lanes_of::<LANES>(&padded)));
        for i in 0..rest.len() {
            sum += r.0[i] * r.0[i];
        }
    }
    sum
}
}

/// Fit the pose of `start` to `points` with at most `max_iterations` accepted or rejected LM
/// steps. `five_dof` fixes the spin about the local z axis (for bodies of revolution, where it
/// is unobservable and would make the normal matrix singular). Stops early when the cost
/// improves by less than `1e-6` relative.
pub fn fit_pose(start: &PlacedSuperquadric, points: &[Point3<f64>], max_iterations: usize, five_dof: bool) -> Fit {
    fit_pose_tol(start, points, max_iterations, five_dof, 1e-6)
}

/// [`fit_pose`] stopping when a step improves the cost by less than `rel_tol` relative.
pub fn fit_pose_tol(
    start: &PlacedSuperquadric,
    points: &[Point3<f64>],
    max_iterations: usize,
    five_dof: bool,
    rel_tol: f64,
) -> Fit {
    let frozen = if five_dof { Freedom::FiveDof } else { Freedom::Free };
    fit_pose_with(start, points, max_iterations, frozen, rel_tol)
}

/// Which of the pose's six degrees of freedom a fit may move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Freedom {
    /// All six.
    Free,
    /// All but the spin about the local z axis (a body of revolution, whose spin nothing
    /// observes).
    FiveDof,
    /// The position and the spin about the local z axis: the axis keeps its direction (a
    /// container standing on the support plane).
    AxisFixed,
}

/// [`fit_pose_tol`] with the degrees of freedom given.
pub fn fit_pose_with(
    start: &PlacedSuperquadric,
    points: &[Point3<f64>],
    max_iterations: usize,
    freedom: Freedom,
    rel_tol: f64,
) -> Fit {
    let problem = PoseFit { points, freedom };
    let found = minimize(&problem, *start, &LmSettings::attempts(max_iterations, rel_tol));
    let m = (found.cost / points.len().max(1) as f64).sqrt();
    Fit {
        placed: found.x,
        m,
        iterations: found.attempts,
    }
}

/// The pose of a superquadric over points, the paper's eq. (2).
struct PoseFit<'a> {
    points: &'a [Point3<f64>],
    freedom: Freedom,
}

impl LeastSquares<6> for PoseFit<'_> {
    type Params = PlacedSuperquadric;
    // Every candidate is evaluated with its normal equations: an accepted step (the usual case
    // once the damping has settled) then needs no second pass over the points.
    type Evaluation = (Matrix6<f64>, Vector6<f64>);

    fn evaluate(&self, placed: &PlacedSuperquadric) -> (f64, Self::Evaluation) {
        let (cost, h, g) = normal_equations(placed, self.points, self.freedom);
        (cost, (h, g))
    }

    fn linearize(&self, _: &PlacedSuperquadric, at: &Self::Evaluation) -> (Matrix6<f64>, Vector6<f64>) {
        *at
    }

    fn step(&self, placed: &PlacedSuperquadric, delta: &Vector6<f64>) -> PlacedSuperquadric {
        placed.perturbed(&(*delta).into())
    }
}

/// Points evaluated together.
pub(super) const LANES: usize = 4;

/// Residuals and Jacobian rows of four points at once. (A trait rather than a closure: a
/// closure's body is compiled apart, without the vector width `widened!` gives its caller.)
pub(super) trait Rows {
    fn rows(&self, p: [Lanes<LANES>; 3]) -> (Lanes<LANES>, [Lanes<LANES>; 6]);
}

/// The rows of a pose fit: one placed shape.
struct PoseRows<'a>(&'a PlacedKernel);

impl Rows for PoseRows<'_> {
    #[inline(always)]
    fn rows(&self, p: [Lanes<LANES>; 3]) -> (Lanes<LANES>, [Lanes<LANES>; 6]) {
        self.0.residual_pose_jacobian_lanes(p)
    }
}

/// The upper triangle of `J^T J` (row by row), `J^T r` and `sum r^2` over `points`, whose
/// residuals and Jacobian rows `eval` gives four at a time. Each lane sums its own share; the
/// last few points are evaluated as one group padded with copies, and summed one by one.
#[inline(always)]
pub(super) fn normal_sums(points: &[Point3<f64>], eval: &impl Rows) -> ([f64; 21], [f64; 6], f64) {
    // J^T J is symmetric: only its upper triangle is summed (21 products a point, not 36).
    let mut upper4 = [Lanes::<LANES>::splat(0.0); 21];
    let mut g4 = [Lanes::<LANES>::splat(0.0); 6];
    let mut cost4 = Lanes::<LANES>::splat(0.0);
    let chunks = points.chunks_exact(LANES);
    let rest = chunks.remainder();
    for c in chunks {
        let (r, j) = eval.rows(lanes_of::<LANES>(c));
        let mut n = 0;
        for a in 0..6 {
            for b in a..6 {
                upper4[n] = upper4[n] + j[a] * j[b];
                n += 1;
            }
            g4[a] = g4[a] + j[a] * r;
        }
        cost4 = cost4 + r * r;
    }
    let mut upper = upper4.map(|v| v.sum());
    let mut g = g4.map(|v| v.sum());
    let mut cost = cost4.sum();
    if !rest.is_empty() {
        let padded: [Point3<f64>; LANES] = std::array::from_fn(|i| rest[i % rest.len()]);
        let (r, j) = eval.rows(lanes_of::<LANES>(&padded));
        for i in 0..rest.len() {
            let r = r.0[i];
            let mut n = 0;
            for a in 0..6 {
                for b in a..6 {
                    upper[n] += j[a].0[i] * j[b].0[i];
                    n += 1;
                }
                g[a] += j[a].0[i] * r;
            }
            cost += r * r;
        }
    }
    (upper, g, cost)
}

/// The symmetric matrix of an upper triangle given row by row.
pub(super) fn symmetric(upper: &[f64; 21]) -> Matrix6<f64> {
    let mut h = Matrix6::<f64>::zeros();
    let mut n = 0;
    for a in 0..6 {
        for b in a..6 {
            h[(a, b)] = upper[n];
            h[(b, a)] = upper[n];
            n += 1;
        }
    }
    h
}

widened! {
/// The cost `sum r^2`, the Gauss-Newton matrix `J^T J` and the gradient `J^T r` at a pose, in
/// one pass over the points. For a 5-DoF fit the spin row and column are replaced by identity.
fn normal_equations(
    placed: &PlacedSuperquadric,
    points: &[Point3<f64>],
    freedom: Freedom,
) -> (f64, Matrix6<f64>, Vector6<f64>) {
    let kernel = PlacedKernel::new(placed);
    let (upper, g, cost) = normal_sums(points, &PoseRows(&kernel));
    let mut h = symmetric(&upper);
    let mut g = Vector6::from(g);
    let frozen: &[usize] = match freedom {
        Freedom::Free => &[],
        Freedom::FiveDof => &[5],
        Freedom::AxisFixed => &[3, 4],
    };
    for &f in frozen {
        for k in 0..6 {
            h[(f, k)] = 0.0;
            h[(k, f)] = 0.0;
        }
        h[(f, f)] = 1.0;
        g[f] = 0.0;
    }
    (cost, h, g)
}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Superquadric;
    use nalgebra::{Isometry3, Vector3};

    #[test]
    fn recovers_a_perturbed_pose_from_a_visible_half() {
        // Not a body of revolution, so all six pose parameters are observable.
        let sq = Superquadric::new([0.06, 0.045, 0.02], 0.4, 0.8, 0.3, 0.1).unwrap();
        let truth = PlacedSuperquadric::new(
            sq,
            Isometry3::new(Vector3::new(0.8, 0.1, 0.74), Vector3::new(0.1, -0.2, 0.3)),
        );
        // The half facing +x+z, as a sensor up and in front would see it.
        let view = Vector3::new(1.0, 0.0, 1.0).normalize();
        let pts: Vec<Point3<f64>> = truth
            .sample_surface(0.004)
            .into_iter()
            .filter(|p| (p - Point3::from(truth.pose.translation.vector)).dot(&view) > 0.0)
            .collect();
        let start = truth.perturbed(&[0.01, -0.008, 0.006, 0.1, -0.08, 0.05]);
        let fit = fit_pose(&start, &pts, 50, false);
        let dt = (fit.placed.pose.translation.vector - truth.pose.translation.vector).norm();
        let dr = fit.placed.pose.rotation.angle_to(&truth.pose.rotation);
        assert!(dt < 1e-5 && dr < 1e-4, "position error {dt} m, rotation error {dr} rad");
        assert!(fit.m < 1e-6, "M = {}", fit.m);
    }

    /// The normal equations and M come out the same to the bit from the AVX2 code and from the
    /// baseline (SSE2) code, where the CPU has both.
    #[test]
    fn the_vector_widths_agree_to_the_bit() {
        use crate::numeric::lanes::BASELINE_ONLY;
        use std::sync::atomic::Ordering;
        let shapes = [
            Superquadric::new([0.06, 0.06, 0.02], 0.4, 1.0, 0.3, 0.3).unwrap(),
            Superquadric::untapered([0.038, 0.038, 0.048], 0.1, 1.0).unwrap(),
            Superquadric::new([0.05, 0.03, 0.02], 0.284, 0.263, -0.2, 0.1).unwrap(),
        ];
        for (i, sq) in shapes.iter().enumerate() {
            let truth = PlacedSuperquadric::new(
                *sq,
                Isometry3::new(Vector3::new(0.8, 0.1, 0.74), Vector3::new(0.1, -0.2, 0.3)),
            );
            let pts: Vec<Point3<f64>> = truth.sample_surface(0.006).into_iter().take(101 + i).collect();
            let at = truth.perturbed(&[0.003, -0.002, 0.001, 0.05, -0.02, 0.03]);
            let run = |baseline: bool| {
                BASELINE_ONLY.store(baseline, Ordering::Relaxed);
                let (c, h, g) = normal_equations(&at, &pts, Freedom::Free);
                let m = measure_of_fit(&at, &pts);
                BASELINE_ONLY.store(false, Ordering::Relaxed);
                (c, h, g, m)
            };
            let (wide, base) = (run(false), run(true));
            assert_eq!(wide.0.to_bits(), base.0.to_bits());
            assert!(
                wide.1
                    .iter()
                    .zip(base.1.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
            assert!(
                wide.2
                    .iter()
                    .zip(base.2.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
            assert_eq!(wide.3.to_bits(), base.3.to_bits());
        }
    }

    #[test]
    fn five_dof_fit_of_a_cylinder_keeps_its_spin() {
        let sq = Superquadric::untapered([0.038, 0.038, 0.048], 0.1, 1.0).unwrap();
        let truth = PlacedSuperquadric::new(sq, Isometry3::translation(0.9, 0.2, 0.77));
        let pts: Vec<Point3<f64>> = truth.sample_surface(0.004).into_iter().filter(|p| p.x < 0.9).collect();
        let start = truth.perturbed(&[0.006, 0.004, -0.005, 0.08, 0.05, 0.3]);
        let fit = fit_pose(&start, &pts, 50, true);
        let axis = fit.placed.pose.rotation * Vector3::z();
        assert!(axis.angle(&Vector3::z()) < 1e-4);
        assert!((fit.placed.pose.translation.vector - truth.pose.translation.vector).norm() < 1e-5);
    }
}
