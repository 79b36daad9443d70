//! Evaluation against the simulator's ground truth: re-simulate a scene with new sensor noise,
//! detect with a new search seed, and score the pose modulo the object's symmetries.

use crate::detect::{self, Params, Report};
use crate::geometry::Superquadric;
use crate::model::Model;
use crate::sim::{self, Scene};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// A detection is correct within these (the paper's grasping tolerance, the criterion).
pub const MAX_POSITION_ERROR_M: f64 = 0.010;
pub const MAX_ROTATION_ERROR_RAD: f64 = 10.0 * PI / 180.0;

/// The rotations that map a model onto itself: a finite set, plus a free spin about the object z
/// axis when every part is a body of revolution on that axis.
#[derive(Debug, Clone)]
pub struct Symmetry {
    pub discrete: Vec<UnitQuaternion<f64>>,
    pub spin_z: bool,
}

fn same_shape(a: &Superquadric, b: &Superquadric) -> bool {
    a.a.iter().zip(&b.a).all(|(x, y)| (x - y).abs() < 1e-9)
        && (a.e1 - b.e1).abs() < 1e-9
        && (a.e2 - b.e2).abs() < 1e-9
        && (a.kx - b.kx).abs() < 1e-9
        && (a.ky - b.ky).abs() < 1e-9
}

/// Whether `g` (a rotation of the object frame about its origin) leaves the model unchanged,
/// checked on surface samples: each moved sample must lie on some part's surface.
fn is_symmetry(model: &Model, g: &UnitQuaternion<f64>) -> bool {
    let moved = Isometry3::from_parts(Default::default(), *g);
    let parts = model.placed_parts(&Isometry3::identity());
    let parts_moved = model.placed_parts(&moved);
    parts_moved.iter().all(|pm| {
        let tol = 1e-3 * pm.shape.min_size();
        pm.sample_surface(pm.shape.min_size() / 3.0).iter().all(|p| {
            parts
                .iter()
                .any(|q| same_shape(&q.shape, &pm.shape) && q.surface_distance(p).abs() < tol)
        })
    })
}

impl Symmetry {
    pub fn of(model: &Model) -> Symmetry {
        let spin_z = model.parts.iter().all(|p| {
            let z = p.pose_in_object.rotation * Vector3::z();
            let t = p.pose_in_object.translation.vector;
            p.shape.is_revolution() && z.cross(&Vector3::z()).norm() < 1e-9 && t.x.abs() < 1e-9 && t.y.abs() < 1e-9
        });
        let mut discrete = vec![UnitQuaternion::identity()];
        for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
            for angle in [PI, 0.5 * PI, -0.5 * PI] {
                let g = UnitQuaternion::from_axis_angle(&axis, angle);
                if is_symmetry(model, &g) {
                    discrete.push(g);
                }
            }
        }
        Symmetry { discrete, spin_z }
    }

    /// The rotation error (rad) of `estimate` against `truth`, modulo the symmetries.
    pub fn rotation_error(&self, estimate: &UnitQuaternion<f64>, truth: &UnitQuaternion<f64>) -> f64 {
        self.discrete
            .iter()
            .map(|g| {
                let t = truth * g;
                if self.spin_z {
                    (estimate * Vector3::z()).angle(&(t * Vector3::z()))
                } else {
                    estimate.angle_to(&t)
                }
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// The ground-truth pose of `model` in a scene: the scene object of the same model, or else the
/// object having a part of the model's (first) part's shape, at that part.
pub fn truth_pose(scene: &Scene, model: &Model) -> Option<(String, Isometry3<f64>)> {
    if let Some(o) = scene.objects.iter().find(|o| o.model.name == model.name) {
        return Some((o.name.clone(), o.pose));
    }
    let part = &model.parts[0];
    for o in &scene.objects {
        for p in &o.model.parts {
            if same_shape(&p.shape, &part.shape) {
                let part_pose = o.pose * p.pose_in_object;
                return Some((o.name.clone(), part_pose * part.pose_in_object.inverse()));
            }
        }
    }
    None
}

/// One trial's outcome.
#[derive(Debug, Clone)]
pub struct Trial {
    pub found: bool,
    pub correct: bool,
    pub position_error: f64,
    pub rotation_error: f64,
    pub time_ms: f64,
    pub report: Report,
}

/// Run one trial: simulate with `noise_seed`, detect with `params` (whose seed is the search seed).
pub fn trial(
    scene: &Scene,
    model: &Model,
    truth: Option<&Isometry3<f64>>,
    symmetry: &Symmetry,
    noise_seed: u64,
    params: &Params,
) -> Trial {
    let sweep = sim::simulate(scene, noise_seed);
    let mut p = params.clone();
    if p.viewpoint.is_none() {
        p.viewpoint = sweep.cloud.viewpoint.map(|v| Point3::new(v[0], v[1], v[2]));
    }
    let report = detect::detect(&sweep.cloud.points, model, &p);
    let best = report.detections.first();
    let found = best.is_some_and(|d| d.found);
    let (position_error, rotation_error) = match (best, truth) {
        (Some(d), Some(t)) => (
            (d.pose.translation.vector - t.translation.vector).norm(),
            symmetry.rotation_error(&d.pose.rotation, &t.rotation),
        ),
        _ => (f64::INFINITY, f64::INFINITY),
    };
    let correct = found && position_error < MAX_POSITION_ERROR_M && rotation_error < MAX_ROTATION_ERROR_RAD;
    Trial {
        found,
        correct,
        position_error,
        rotation_error,
        time_ms: report.timing.total_ms,
        report,
    }
}

/// Median and 95th percentile of the finite values.
pub fn median_p95(values: &[f64]) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
    (q(0.5), q(0.95))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn model(name: &str) -> Model {
        Model::load(name, &Path::new(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap()
    }

    #[test]
    fn symmetries_of_the_shipped_models() {
        // A cylinder: free spin about z, and upside down is the same.
        let s = Symmetry::of(&model("cup_body"));
        assert!(s.spin_z);
        assert!(s.discrete.len() >= 2);
        // The tapered bowl spins freely but cannot be turned over.
        let s = Symmetry::of(&model("bowl"));
        assert!(s.spin_z);
        let flip = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI);
        assert!(s.rotation_error(&flip, &UnitQuaternion::identity()) > 3.0);
        // The cup's handle fixes the spin; turning it over about the handle's direction (x) maps
        // body and handle onto themselves.
        let s = Symmetry::of(&model("cup"));
        assert!(!s.spin_z);
        assert!(s.rotation_error(&flip, &UnitQuaternion::identity()) < 1e-9);
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.5);
        assert!((s.rotation_error(&yaw, &UnitQuaternion::identity()) - 0.5).abs() < 1e-9);
    }
}
