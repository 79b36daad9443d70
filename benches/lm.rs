//! The detector's hand-written 6x6 Levenberg-Marquardt (`sqscan::detect::fit`) against the
//! `levenberg-marquardt` crate, on the problem the detector solves thousands of times per scene:
//! the pose of a model superquadric fitted to about 30 noisy points of its visible side, started
//! from a perturbed pose.
//!
//! Both solvers get the same residual and Jacobian (`PlacedSuperquadric::residual_pose_jacobian`
//! from `src/geometry`), the same iteration cap and the same relative cost tolerance as far as
//! the crate allows (it counts residual evaluations, `patience * (n + 1)`, not steps; its `ftol`
//! asks for the actual and the predicted relative reduction both below it). Bodies of revolution
//! are fitted in 5 DoF by both (the spin is not a parameter), as the detector does.
//!
//! The crate's newest release (0.15.0) is built on nalgebra 0.34, the project on 0.35, so the
//! crate is a dev-dependency with its own nalgebra (`nalgebra-034`): the problem is copied into
//! that nalgebra's matrices, which is the conversion any use of the crate here would need.
//!
//! `cargo bench --bench lm --features lm-bench -- --noplot` prints an accuracy table first (final cost, pose error,
//! iterations; computed once, outside the timing), then criterion's time for a batch of fits.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use nalgebra_034 as na34;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use sqscan::detect::{fit_pose_tol, measure_of_fit};
use sqscan::geometry::{PlacedSuperquadric, Superquadric};
use sqscan::model::Model;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

/// Points per fit: the detector's trial sample.
const POINTS: usize = 30;
/// The detector's `Params::fit_iterations`.
const MAX_ITERATIONS: usize = 20;
/// `fit_pose`'s relative cost tolerance.
const REL_TOL: f64 = 1e-6;
/// Problems per model.
const PROBLEMS: usize = 50;
/// Sensor noise along each axis, metres.
const NOISE: f64 = 0.0005;
/// Start perturbation: standard deviation per axis, metres and radians.
const START_T: f64 = 0.005;
const START_R: f64 = 0.1;

struct Problem {
    truth: PlacedSuperquadric,
    start: PlacedSuperquadric,
    points: Vec<Point3<f64>>,
}

fn gauss(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    let n: f64 = StandardNormal.sample(rng);
    sigma * n
}

fn problems(shape: Superquadric, seed: u64) -> Vec<Problem> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..PROBLEMS)
        .map(|_| {
            // A pose in front of the sensor (at the origin looking along +x, from above).
            let axis = Vector3::new(gauss(&mut rng, 0.2), gauss(&mut rng, 0.2), gauss(&mut rng, 1.0));
            let truth = PlacedSuperquadric::new(
                shape,
                Isometry3::new(Vector3::new(0.8, gauss(&mut rng, 0.1), -0.3), axis.normalize() * 0.3),
            );
            let centre = Point3::from(truth.pose.translation.vector);
            let view = (Point3::origin() - centre).normalize();
            let visible: Vec<Point3<f64>> = truth
                .sample_surface(0.002)
                .into_iter()
                .filter(|p| (p - centre).dot(&view) > 0.0)
                .collect();
            let points = (0..POINTS)
                .map(|_| {
                    let p = visible[rng.random_range(0..visible.len())];
                    p + Vector3::new(gauss(&mut rng, NOISE), gauss(&mut rng, NOISE), gauss(&mut rng, NOISE))
                })
                .collect();
            let mut delta = [0.0; 6];
            for (k, d) in delta.iter_mut().enumerate() {
                *d = gauss(&mut rng, if k < 3 { START_T } else { START_R });
            }
            if shape.is_revolution() {
                delta[5] = 0.0;
            }
            Problem {
                truth,
                start: truth.perturbed(&delta),
                points,
            }
        })
        .collect()
}

/// The same least-squares problem for the crate: parameters `x` are a perturbation of the start
/// pose (`start.perturbed(x)`, spin fixed at 0 in 5 DoF). The crate works in a flat parameter
/// space, so the local rotation Jacobian of `residual_pose_jacobian` is chained with SO(3)'s right
/// Jacobian at `x` to give the exact derivative with respect to `x`.
struct CrateProblem<'a, const D: usize> {
    start: PlacedSuperquadric,
    points: &'a [Point3<f64>],
    x: na34::SVector<f64, D>,
    current: PlacedSuperquadric,
}

impl<'a, const D: usize> CrateProblem<'a, D> {
    fn new(start: PlacedSuperquadric, points: &'a [Point3<f64>]) -> Self {
        Self {
            start,
            points,
            x: na34::SVector::zeros(),
            current: start,
        }
    }

    fn delta(x: &na34::SVector<f64, D>) -> [f64; 6] {
        let mut d = [0.0; 6];
        d[..D].copy_from_slice(x.as_slice());
        d
    }
}

/// SO(3)'s right Jacobian: `exp(w + dw) = exp(w) exp(J_r(w) dw)` to first order.
fn right_jacobian(w: &Vector3<f64>) -> nalgebra::Matrix3<f64> {
    let theta = w.norm();
    let k = w.cross_matrix();
    if theta < 1e-8 {
        return nalgebra::Matrix3::identity() - 0.5 * k;
    }
    let t2 = theta * theta;
    nalgebra::Matrix3::identity() - (1.0 - theta.cos()) / t2 * k + (theta - theta.sin()) / (t2 * theta) * k * k
}

impl<const D: usize> LeastSquaresProblem<f64, na34::Dyn, na34::Const<D>> for CrateProblem<'_, D> {
    type ResidualStorage = na34::VecStorage<f64, na34::Dyn, na34::U1>;
    type JacobianStorage = na34::VecStorage<f64, na34::Dyn, na34::Const<D>>;
    type ParameterStorage = na34::ArrayStorage<f64, D, 1>;

    fn set_params(&mut self, x: &na34::SVector<f64, D>) {
        self.x = *x;
        self.current = self.start.perturbed(&Self::delta(x));
    }

    fn params(&self) -> na34::SVector<f64, D> {
        self.x
    }

    fn residuals(&self) -> Option<na34::DVector<f64>> {
        Some(na34::DVector::from_iterator(
            self.points.len(),
            self.points.iter().map(|p| self.current.residual(p)),
        ))
    }

    fn jacobian(&self) -> Option<na34::OMatrix<f64, na34::Dyn, na34::Const<D>>> {
        let d = Self::delta(&self.x);
        let jr = right_jacobian(&Vector3::new(d[3], d[4], d[5]));
        let mut j = na34::OMatrix::<f64, na34::Dyn, na34::Const<D>>::zeros(self.points.len());
        for (i, p) in self.points.iter().enumerate() {
            let (_, g) = self.current.residual_pose_jacobian(p);
            let rot = jr.transpose() * Vector3::new(g[3], g[4], g[5]);
            let row = [g[0], g[1], g[2], rot.x, rot.y, rot.z];
            for k in 0..D {
                j[(i, k)] = row[k];
            }
        }
        Some(j)
    }
}

fn crate_solver(dof: usize) -> LevenbergMarquardt<f64> {
    // Residual evaluations allowed: at least MAX_ITERATIONS + 1 (one per step and the start).
    let patience = (MAX_ITERATIONS + 1).div_ceil(dof + 1);
    LevenbergMarquardt::new().with_ftol(REL_TOL).with_patience(patience)
}

/// Fitted pose and iteration count (steps for ours, residual evaluations for the crate).
fn fit_ours(p: &Problem) -> (PlacedSuperquadric, usize) {
    let f = fit_pose_tol(
        &p.start,
        &p.points,
        MAX_ITERATIONS,
        p.start.shape.is_revolution(),
        REL_TOL,
    );
    (f.placed, f.iterations)
}

fn fit_crate(solver: &LevenbergMarquardt<f64>, p: &Problem) -> (PlacedSuperquadric, usize) {
    if p.start.shape.is_revolution() {
        let (prob, report) = solver.minimize(CrateProblem::<5>::new(p.start, &p.points));
        (prob.current, report.number_of_evaluations)
    } else {
        let (prob, report) = solver.minimize(CrateProblem::<6>::new(p.start, &p.points));
        (prob.current, report.number_of_evaluations)
    }
}

/// Position error (m) and rotation error (rad) modulo the shape's symmetries: the axis only for
/// a body of revolution (folded when untapered), else the rotation with a half turn about z.
fn pose_error(shape: &Superquadric, fitted: &PlacedSuperquadric, truth: &PlacedSuperquadric) -> (f64, f64) {
    let dt = (fitted.pose.translation.vector - truth.pose.translation.vector).norm();
    let dr = if shape.is_revolution() {
        let za = fitted.pose.rotation * Vector3::z();
        let zb = truth.pose.rotation * Vector3::z();
        sqscan::model::axis_angle(&za, &zb, shape.is_tapered())
    } else {
        let half = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
        let a = fitted.pose.rotation.angle_to(&truth.pose.rotation);
        let b = (fitted.pose.rotation * half).angle_to(&truth.pose.rotation);
        a.min(b)
    };
    (dt, dr)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn p95(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[(v.len() * 95).div_ceil(100) - 1]
}

fn accuracy_table(cases: &[(String, Vec<Problem>)]) {
    println!(
        "| model | DoF | solver | cost sum r^2 (median / p95) | start cost (median) | position error mm (median / p95) | rotation error deg (median / p95) | iterations (median / max) | largest cost difference to hand-written |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, probs) in cases {
        let shape = probs[0].start.shape;
        let dof = if shape.is_revolution() { 5 } else { 6 };
        let start_cost = median(
            probs
                .iter()
                .map(|p| measure_of_fit(&p.start, &p.points).powi(2) * p.points.len() as f64)
                .collect(),
        );
        let solver = crate_solver(dof);
        let mut ours_cost: Vec<f64> = Vec::new();
        for which in ["hand-written", "levenberg-marquardt 0.15"] {
            let (mut cost, mut et, mut er, mut it) = (vec![], vec![], vec![], vec![]);
            for p in probs {
                let (placed, iterations) = if which == "hand-written" {
                    fit_ours(p)
                } else {
                    fit_crate(&solver, p)
                };
                cost.push(measure_of_fit(&placed, &p.points).powi(2) * p.points.len() as f64);
                let (t, r) = pose_error(&shape, &placed, &p.truth);
                et.push(t * 1e3);
                er.push(r.to_degrees());
                it.push(iterations as f64);
            }
            let max_it = it.iter().copied().fold(0.0, f64::max);
            let diff = if which == "hand-written" {
                ours_cost = cost.clone();
                "".to_string()
            } else {
                // Relative: (crate - ours) / ours, the largest in absolute value over the problems.
                let d = cost
                    .iter()
                    .zip(&ours_cost)
                    .map(|(c, o)| (c - o) / o)
                    .fold(0.0, |a: f64, d| if d.abs() > a.abs() { d } else { a });
                format!("{d:+.1e}")
            };
            println!(
                "| {name} | {dof} | {which} | {:.3e} / {:.3e} | {:.3e} | {:.3} / {:.3} | {:.3} / {:.3} | {} / {} | {diff} |",
                median(cost.clone()),
                p95(cost),
                start_cost,
                median(et.clone()),
                p95(et),
                median(er.clone()),
                p95(er),
                median(it),
                max_it
            );
        }
    }
}

fn bench(c: &mut Criterion) {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    // The bowl, cup body and mallet head are bodies of revolution (5 DoF, as the detector fits
    // them); the mouse is not, so it exercises the full 6-DoF system.
    let cases: Vec<(String, Vec<Problem>)> = ["bowl", "cup_body", "mallet_head", "mouse"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let model = Model::load(name, &models).expect("shipped model");
            (name.to_string(), problems(model.parts[0].shape, 1000 + i as u64))
        })
        .collect();
    accuracy_table(&cases);

    let mut g = c.benchmark_group("lm");
    g.sample_size(30).measurement_time(Duration::from_secs(4));
    for (name, probs) in &cases {
        let dof = if probs[0].start.shape.is_revolution() { 5 } else { 6 };
        let solver = crate_solver(dof);
        // One iteration fits all PROBLEMS problems: divide the time by PROBLEMS for one fit.
        g.bench_with_input(BenchmarkId::new("hand-written", name), probs, |b, probs| {
            b.iter(|| {
                for p in probs {
                    black_box(fit_ours(black_box(p)));
                }
            })
        });
        g.bench_with_input(BenchmarkId::new("levenberg-marquardt", name), probs, |b, probs| {
            b.iter(|| {
                for p in probs {
                    black_box(fit_crate(&solver, black_box(p)));
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
