//! The symmetries of an object model: the rotations that map it onto itself. Used to score
//! poses modulo symmetry (evaluation) and to report one canonical pose among the equivalent
//! ones (the detector turns a sign-free object "z up").

use std::f64::consts::PI;
use std::sync::{Arc, Mutex};

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

use crate::geometry::Superquadric;
use crate::model::Model;

/// The rotations that map a model onto itself: a finite set, plus a free spin about the object z
/// axis when every part is a body of revolution on that axis.
#[derive(Debug, Clone)]
pub struct Symmetry {
    pub discrete: Vec<UnitQuaternion<f64>>,
    pub spin_z: bool,
}

/// Whether two shapes are the same to 1e-9 (size, exponents, taper).
pub fn same_shape(a: &Superquadric, b: &Superquadric) -> bool {
    a.a.iter().zip(&b.a).all(|(x, y)| (x - y).abs() < 1e-9)
        && (a.e1 - b.e1).abs() < 1e-9
        && (a.e2 - b.e2).abs() < 1e-9
        && (a.kx - b.kx).abs() < 1e-9
        && (a.ky - b.ky).abs() < 1e-9
}

/// Whether `g` (a rotation of the object frame about its origin) leaves the model unchanged,
/// checked on surface samples of each part (`samples`, in the object frame): each moved sample
/// must lie on some part's surface.
fn is_symmetry(model: &Model, samples: &[Vec<Point3<f64>>], g: &UnitQuaternion<f64>) -> bool {
    // An open part's opening is not a surface, so turning it to face the other way changes the
    // object even where the shape is the same (a mug's cylinder upside down is a mug on its rim).
    let opening_kept = model.parts.iter().filter(|p| p.open).all(|p| {
        let axis = p.pose_in_object.rotation * Vector3::z();
        let moved_axis = g * axis;
        model
            .parts
            .iter()
            .filter(|q| q.open && same_shape(&q.shape, &p.shape))
            .any(|q| (q.pose_in_object.rotation * Vector3::z()).dot(&moved_axis) > 1.0 - 1e-6)
    });
    if !opening_kept {
        return false;
    }
    // A part moved by g has the moved samples of the part: each part is sampled once (by the
    // caller), not once for every rotation tried.
    let parts = model.placed_parts(&Isometry3::identity());
    model.parts.iter().zip(samples).all(|(pm, samples)| {
        let tol = 1e-3 * pm.shape.min_size();
        samples.iter().all(|p| {
            let p = g * p;
            parts
                .iter()
                .any(|q| same_shape(&q.shape, &pm.shape) && q.surface_distance(&p).abs() < tol)
        })
    })
}

/// The symmetries of the models asked about lately, by their geometry to the bit: finding them
/// samples every part, which costs as much as a twentieth of a compound's detection, and a
/// daemon asks about the same models sweep after sweep.
static CACHE: Mutex<Vec<(Vec<u64>, Arc<Symmetry>)>> = Mutex::new(Vec::new());

/// Models at most in [`CACHE`].
const CACHED_MODELS: usize = 16;

/// What the symmetries depend on: every part's shape, pose in the object frame and opening.
fn geometry_key(model: &Model) -> Vec<u64> {
    let mut key = Vec::with_capacity(15 * model.parts.len());
    for p in &model.parts {
        let s = &p.shape;
        let t = &p.pose_in_object.translation.vector;
        let q = p.pose_in_object.rotation.coords;
        key.extend(
            [
                s.a[0], s.a[1], s.a[2], s.e1, s.e2, s.kx, s.ky, t.x, t.y, t.z, q.x, q.y, q.z, q.w,
            ]
            .map(f64::to_bits),
        );
        key.push(p.open as u64);
    }
    key
}

impl Symmetry {
    /// [`Symmetry::of`], found once for each model's geometry and kept.
    pub fn cached(model: &Model) -> Arc<Symmetry> {
        let key = geometry_key(model);
        let lookup =
            |cache: &Vec<(Vec<u64>, Arc<Symmetry>)>| cache.iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone());
        // A poisoned lock only means another thread panicked while holding it: the list is still
        // a list of finished entries.
        if let Some(hit) = lookup(&CACHE.lock().unwrap_or_else(|e| e.into_inner())) {
            return hit;
        }
        let found = Arc::new(Symmetry::of(model));
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(hit) = lookup(&cache) {
            return hit;
        }
        if cache.len() >= CACHED_MODELS {
            cache.remove(0);
        }
        cache.push((key, found.clone()));
        found
    }

    pub fn of(model: &Model) -> Symmetry {
        let spin_z = model.parts.iter().all(|p| {
            let z = p.pose_in_object.rotation * Vector3::z();
            let t = p.pose_in_object.translation.vector;
            p.shape.is_revolution() && z.cross(&Vector3::z()).norm() < 1e-9 && t.x.abs() < 1e-9 && t.y.abs() < 1e-9
        });
        let samples: Vec<Vec<Point3<f64>>> = model
            .placed_parts(&Isometry3::identity())
            .iter()
            .map(|p| p.sample_surface(p.shape.min_size() / 3.0))
            .collect();
        let mut discrete = vec![UnitQuaternion::identity()];
        for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
            for angle in [PI, 0.5 * PI, -0.5 * PI] {
                let g = UnitQuaternion::from_axis_angle(&axis, angle);
                if is_symmetry(model, &samples, &g) {
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

    /// Among the poses equivalent under the discrete symmetries, the one whose object z axis
    /// points most along `up` (the support plane's normal): a cup fitted upside down, which is
    /// the same cup, is reported standing. Identity when no symmetry turns z over.
    pub fn canonical_up(&self, rotation: &UnitQuaternion<f64>, up: &Vector3<f64>) -> UnitQuaternion<f64> {
        let mut best = *rotation;
        let mut best_dot = (rotation * Vector3::z()).dot(up);
        for g in &self.discrete {
            let r = rotation * g;
            let d = (r * Vector3::z()).dot(up);
            // A clear margin: symmetries that keep z (a quarter turn about z) never replace the
            // fitted rotation.
            if d > best_dot + 1e-6 {
                best = r;
                best_dot = d;
            }
        }
        best
    }
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

    #[test]
    fn canonical_pose_stands_up() {
        let s = Symmetry::of(&model("cup"));
        let upside_down = UnitQuaternion::from_euler_angles(PI, 0.0, -1.0);
        let c = s.canonical_up(&upside_down, &Vector3::z());
        assert!((c * Vector3::z()).z > 0.999, "{c:?}");
        // The same object: zero error modulo symmetry, and the yaw (handle direction) is kept.
        assert!(s.rotation_error(&c, &upside_down) < 1e-9);
        assert!(((c * Vector3::x()).y.atan2((c * Vector3::x()).x) + 1.0).abs() < 1e-9);
        // A bowl cannot be turned over: left as fitted.
        let b = Symmetry::of(&model("bowl"));
        assert_eq!(b.canonical_up(&upside_down, &Vector3::z()), upside_down);
    }

    /// A model's symmetries are found once and kept by its geometry: the same model (and a copy
    /// of it under another name) gets the same set, another model its own.
    #[test]
    fn symmetries_are_kept_by_geometry() {
        let cup = model("cup");
        let first = Symmetry::cached(&cup);
        let found = Symmetry::of(&cup);
        assert_eq!(first.spin_z, found.spin_z);
        assert_eq!(first.discrete, found.discrete);
        let mut renamed = cup.clone();
        renamed.name = "another_cup".into();
        assert!(Arc::ptr_eq(&first, &Symmetry::cached(&renamed)));
        let mut moved = cup.clone();
        moved.parts[1].pose_in_object.translation.vector.z += 0.01;
        assert!(!Arc::ptr_eq(&first, &Symmetry::cached(&moved)));
        let bowl = Symmetry::cached(&model("bowl"));
        assert!(bowl.spin_z && !first.spin_z);
    }
}
