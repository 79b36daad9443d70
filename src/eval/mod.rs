//! Evaluation against the simulator's ground truth: re-simulate a scene with new sensor noise,
//! detect with a new search seed, and score the pose modulo the object's symmetries.

pub mod grasps;
pub mod real;

use crate::detect::{self, Params, Report};
use crate::model::Model;
use crate::numeric::quantile;
use crate::sim::{self, Scene};
pub use crate::symmetry::Symmetry;
use crate::symmetry::same_shape;
use nalgebra::Isometry3;
use std::f64::consts::PI;

/// A detection is correct within these (the paper's grasping tolerance, the criterion).
pub const MAX_POSITION_ERROR_M: f64 = 0.010;
pub const MAX_ROTATION_ERROR_RAD: f64 = 10.0 * PI / 180.0;

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
    /// The simulated sweep's points the detection ran on, and where it was seen from.
    pub cloud: Vec<[f32; 3]>,
    pub viewpoint: Option<nalgebra::Point3<f64>>,
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
        p.viewpoint = sweep.cloud.viewpoint_position();
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
        cloud: sweep.cloud.points,
        viewpoint: p.viewpoint,
    }
}

/// Median and 95th percentile of the finite values.
pub fn median_p95(values: &[f64]) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    let median = quantile(&mut v, 0.5).unwrap_or(f64::NAN);
    (median, quantile(&mut v, 0.95).unwrap_or(f64::NAN))
}
