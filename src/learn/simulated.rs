//! Learning from simulated single-object scans, scored against the simulator's truth: what the
//! tests and the error table of BENCHMARKS.md (`sqscan learn --simulate MODEL`) run.

use super::params::{LearnError, LearnParams};
use super::{Learned, learn};
use crate::cloud::PointCloud;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::model::Model;
use crate::sim::{self, Scene};
use nalgebra::{Point3, Vector3};
use std::path::Path;

/// The fig3 rig (paper Fig. 3 scene) with a table and one object.
pub fn scene_toml(model_path: &Path, position: [f64; 2], rpy_deg: [f64; 3]) -> String {
    format!(
        r#"description = "one object for sqscan learn"
[table]
height = 0.72
center = [0.85, 0.0]
size = [1.2, 1.6]

[rig]
ptu = {{ position = [0.0, 0.0, 1.35] }}
sensor_mount = {{ position = [0.05, 0.0, 0.08] }}
pan = 0.0
profiles = 150
tilt_start = 0.49
tilt_end = 0.84
tilt_speed = 0.12
columns = 256
fov_deg = 40.0
baseline = 0.15
range_min = 0.5
range_max = 1.6
noise_sigma_at_1m = 0.002
dropout = 0.01
max_incidence_deg = 80.0

[[object]]
name = "object"
model = {:?}
pose = {{ position = [{}, {}, 0.0], rpy_deg = [{}, {}, {}] }}
"#,
        model_path.display().to_string(),
        position[0],
        position[1],
        rpy_deg[0],
        rpy_deg[1],
        rpy_deg[2]
    )
}

/// How a single-part model rests on the table in the tests: slender parts (z more than twice the
/// other sizes) lie on their side, everything else stands on its z axis; turned by a yaw that
/// lines no axis up with the sensor.
pub fn resting_rpy_deg(sq: &Superquadric) -> [f64; 3] {
    if sq.a[2] > 2.0 * sq.a[0].max(sq.a[1]) {
        [0.0, 90.0, 30.0]
    } else {
        [0.0, 0.0, 25.0]
    }
}

/// Errors of a learned shape against the truth, after matching the learned axes to the true
/// ones by their direction in the world (a symmetric equivalent, such as a1 and a2 swapped with
/// a 90-degree turn, gives the same errors).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ShapeErrors {
    /// Learned size minus true size along each true axis (m).
    pub da: [f64; 3],
    pub de1: f64,
    pub de2: f64,
    /// The learned axis matched to each true axis.
    pub axis_of: [usize; 3],
    /// The learned z axis is the true z axis (else the exponents are compared as for a shape
    /// symmetric under axis permutations, `e1 = e2`).
    pub z_matches: bool,
    /// Centre error (m).
    pub centre: f64,
}

impl ShapeErrors {
    pub fn max_size_error(&self) -> f64 {
        self.da.iter().fold(0.0f64, |m, d| m.max(d.abs()))
    }

    pub fn max_exponent_error(&self) -> f64 {
        self.de1.abs().max(self.de2.abs())
    }
}

pub fn compare(truth: &PlacedSuperquadric, learned: &PlacedSuperquadric) -> ShapeErrors {
    let ta: [Vector3<f64>; 3] = [0, 1, 2].map(|k| truth.pose.rotation * Vector3::ith(k, 1.0));
    let la: [Vector3<f64>; 3] = [0, 1, 2].map(|k| learned.pose.rotation * Vector3::ith(k, 1.0));
    // The permutation of the learned axes that best aligns them with the true ones.
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let axis_of = *perms
        .iter()
        .max_by(|p, q| {
            let s = |p: &[usize; 3]| (0..3).map(|k| ta[k].dot(&la[p[k]]).abs()).sum::<f64>();
            s(p).total_cmp(&s(q))
        })
        .unwrap();
    let (t, l) = (&truth.shape, &learned.shape);
    let da = [0, 1, 2].map(|k| l.a[axis_of[k]] - t.a[k]);
    let z_matches = axis_of[2] == 2;
    let (de1, de2) = if z_matches {
        (l.e1 - t.e1, l.e2 - t.e2)
    } else {
        // Only an untapered shape with e1 = e2 keeps its exponents under an axis permutation.
        (l.e1 - t.e1, l.e2 - t.e2).max_abs_pair(l.e1 - t.e2, l.e2 - t.e1)
    };
    ShapeErrors {
        da,
        de1,
        de2,
        axis_of,
        z_matches,
        centre: (learned.pose.translation.vector - truth.pose.translation.vector).norm(),
    }
}

trait PairMin {
    fn max_abs_pair(self, a: f64, b: f64) -> (f64, f64);
}

impl PairMin for (f64, f64) {
    /// The pair (of two readings) whose larger magnitude is smaller.
    fn max_abs_pair(self, a: f64, b: f64) -> (f64, f64) {
        if self.0.abs().max(self.1.abs()) <= a.abs().max(b.abs()) {
            self
        } else {
            (a, b)
        }
    }
}

/// One simulated trial.
#[derive(Debug, Clone)]
pub struct SimTrial {
    pub truth: PlacedSuperquadric,
    pub learned: Learned,
    pub errors: ShapeErrors,
    pub points: usize,
    pub seconds: f64,
}

/// The noise seed of sweep `k` of a trial with seed `seed`: sweep 0 is the single sweep of that
/// seed; the others differ from every other trial's sweeps.
pub fn sweep_seed(seed: u64, k: usize) -> u64 {
    seed ^ ((k as u64) << 32)
}

/// Simulate the model alone on the table with sensor noise `seed`, learn it from the per-pixel
/// median of `sweeps` sweeps of that one view (1: the single sweep), compare.
pub fn learn_simulated(
    model: &Model,
    rpy_deg: Option<[f64; 3]>,
    seed: u64,
    sweeps: usize,
    params: &LearnParams,
) -> Result<SimTrial, LearnError> {
    let sq = model.parts[0].shape;
    let rpy = rpy_deg.unwrap_or_else(|| resting_rpy_deg(&sq));
    let text = scene_toml(&model.source, [0.85, 0.05], rpy);
    let scene = Scene::from_toml_str(&text, Path::new("learn-scene.toml"), Path::new("models"))
        .expect("the generated scene is valid");
    let truth = scene.objects[0].model.placed_parts(&scene.objects[0].pose)[0];
    let clouds: Vec<PointCloud> = (0..sweeps.max(1))
        .map(|k| sim::simulate(&scene, sweep_seed(seed, k)).cloud)
        .collect();
    let cloud = PointCloud::median_of_sweeps(&clouds).expect("the sweeps of one simulated rig match");
    let points: Vec<Point3<f64>> = cloud.finite_points();
    let mut params = params.clone();
    if params.viewpoint.is_none() {
        params.viewpoint = cloud.viewpoint_position();
    }
    let started = std::time::Instant::now();
    let learned = learn(&points, &params)?;
    let seconds = started.elapsed().as_secs_f64();
    let errors = compare(&truth, &learned.parts[0].placed);
    Ok(SimTrial {
        truth,
        learned,
        errors,
        points: points.len(),
        seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::FieldData;
    use crate::sim::simulate;
    use std::path::PathBuf;

    fn models_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
    }

    /// An open container is seen into: the laser goes in through the opening and the camera sees the
    /// inner far wall through it, as a real scanner does. The far wall of a closed one
    /// stays hidden.
    #[test]
    fn the_inside_of_an_open_mug_is_seen_through_its_opening() {
        // The learner's single-object scene (the fig3 rig, 2 mm noise).
        let scene_with = |model: &str| {
            let text = scene_toml(&models_dir().join(format!("{model}.toml")), [0.85, 0.05], [0.0; 3]);
            Scene::from_toml_str(&text, Path::new("test.toml"), &models_dir()).unwrap()
        };
        // Object points behind the vertical axis as seen from the sensor, off the bottom and the rim.
        let far_wall = |scene: &Scene| {
            let sweep = simulate(scene, 1);
            let part = scene.objects[0].model.placed_parts(&scene.objects[0].pose)[0];
            let c = part.pose.translation.vector;
            let v = sweep.cloud.viewpoint_position().unwrap().coords;
            let away = Vector3::new(c.x - v.x, c.y - v.y, 0.0).normalize();
            let labels = match &sweep.cloud.fields[1].data {
                FieldData::U32(l) => l.clone(),
                _ => unreachable!(),
            };
            let mut far = 0;
            for (p, l) in sweep.cloud.points.iter().zip(&labels) {
                if !p[0].is_finite() || *l < 20 {
                    continue;
                }
                let p = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                let d = p - c;
                if d.dot(&away) > 0.01 && d.z.abs() < 0.8 * part.shape.a[2] {
                    far += 1;
                }
            }
            far
        };
        let far = far_wall(&scene_with("mug"));
        assert!(far > 100, "open mug: {far} far-wall points");
        let far = far_wall(&scene_with("cup_body"));
        assert!(far == 0, "closed cup: {far} far-wall points");
    }
}
