//! What the support plane allows: a part resting on it does not reach through it, and an open
//! container stands on its base or its rim.

use super::sample_cache::{LocalSamples, local_samples};
use super::search::SearchSpace;
use crate::cloud::plane::Plane;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use nalgebra::{Point3, Vector3};
use std::sync::Arc;

/// How a shape may be placed against the support plane: its surface samples, to find how deep a
/// pose would push it through the plane.
pub struct PlaneCheck {
    /// Surface points (with normals, unused here), kept between detections.
    samples: Arc<LocalSamples>,
    /// How deep (m) a pose may reach through the plane: the noise and the model's approximation.
    pub(super) tolerance: f64,
    /// The part is an open container: it rests on its base or on its rim.
    open: bool,
}

/// How far (rad) an open container's axis may lean from the support plane's normal. A mug or a
/// bowl at rest stands on its base or on its rim; one lying on its side would show its opening
/// to the side, and a container model laid on its side fits the faces of boxes and lying cans
/// (mOSD learn6, learn30). The tolerance takes the plane's and the fit's errors and a container
/// standing on something uneven.
pub const MAX_REST_TILT: f64 = 0.35;

/// How far, beyond the noise, a real object's surface may lie from the superquadric that models
/// it: a tenth of the smallest size. The model approximates the object (a bowl's curved wall by
/// a linear taper, a mug's rounded foot by a flat end).
pub fn approximation_tolerance(shape: &Superquadric) -> f64 {
    0.1 * shape.min_size()
}

impl PlaneCheck {
    pub fn new(shape: &Superquadric, noise: f64, open: bool) -> PlaneCheck {
        // The model approximates the object: allow the approximation tolerance of overlap beyond
        // the noise before calling a pose impossible.
        // Samples half the smallest size apart find the lowest point to well within the
        // tolerance (the sagitta between samples is a small fraction of the spacing).
        PlaneCheck {
            samples: local_samples(shape, shape.min_size() / 2.0, false),
            tolerance: 3.0 * noise + approximation_tolerance(shape),
            open,
        }
    }

    /// The axis an open container's z must lie along (either way): the plane's normal.
    pub fn rest_axis(&self, space: &SearchSpace<'_>) -> Option<Vector3<f64>> {
        if self.open { space.plane.map(|p| p.normal) } else { None }
    }

    /// How far (m) the placed shape reaches through the plane (negative: it stays above).
    pub fn penetration(&self, placed: &PlacedSuperquadric, plane: &Plane) -> f64 {
        let n_local = placed.pose.rotation.inverse() * plane.normal;
        let lowest = self
            .samples
            .iter()
            .map(|(q, _)| n_local.dot(q))
            .fold(f64::INFINITY, f64::min);
        -(plane.signed_distance(&Point3::from(placed.pose.translation.vector)) + lowest)
    }

    /// Whether the pose is possible for an object resting on or above the plane: it does not
    /// reach through it, and an open container stands on its base or its rim.
    pub fn allows(&self, space: &SearchSpace<'_>, placed: &PlacedSuperquadric) -> bool {
        space.plane.as_ref().is_none_or(|p| {
            let z = placed.pose.rotation * Vector3::z();
            self.penetration(placed, p) <= self.tolerance
                && (!self.open || z.dot(&p.normal).abs() >= MAX_REST_TILT.cos())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The check's samples are the shape's surface at half its smallest size, sampled once and
    /// shared by every check of that shape.
    #[test]
    fn plane_checks_of_one_shape_share_its_samples() {
        let shape = Superquadric::new([0.03, 0.03, 0.05], 0.4, 1.0, 0.2, 0.2).unwrap();
        let a = PlaneCheck::new(&shape, 0.001, true);
        let b = PlaneCheck::new(&shape, 0.002, false);
        assert!(Arc::ptr_eq(&a.samples, &b.samples));
        let fresh = shape.sample_surface(shape.min_size() / 2.0);
        let kept: Vec<Vector3<f64>> = a.samples.iter().map(|(q, _)| *q).collect();
        assert_eq!(kept, fresh);
        assert!(a.tolerance < b.tolerance, "the noise sets the tolerance");
    }
}
