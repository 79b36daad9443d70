//! What the support plane allows: a part resting on it does not reach through it, and an open
//! container stands on its base or its rim.

use super::space::SearchSpace;
use crate::cloud::plane::Plane;
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::surface_samples::{LocalSamples, local_samples};
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

    /// Whether the placed shape reaches through the plane by more than `depth` (m), that is
    /// [`PlaneCheck::penetration`] `> depth`, in fewer steps: the box the shape lies in settles
    /// most poses that stay clear, and a pose that reaches deeper is settled by the first sample
    /// past the limit.
    fn reaches_through(&self, placed: &PlacedSuperquadric, plane: &Plane, depth: f64) -> bool {
        let n_local = placed.pose.rotation.inverse() * plane.normal;
        // Deeper than `depth` where a point lies below this along the normal (local frame).
        let limit = -(plane.signed_distance(&Point3::from(placed.pose.translation.vector)) + depth);
        let ext = placed.shape.local_half_extents();
        let box_lowest = -(n_local.x.abs() * ext.x + n_local.y.abs() * ext.y + n_local.z.abs() * ext.z);
        box_lowest < limit && self.samples.iter().any(|(q, _)| n_local.dot(q) < limit)
    }

    /// Whether a trial may start from `placed`: it reaches through the plane by no more than
    /// `slack` beyond what [`PlaneCheck::allows`].
    pub fn may_start(&self, space: &SearchSpace<'_>, placed: &PlacedSuperquadric, slack: f64) -> bool {
        space
            .plane
            .as_ref()
            .is_none_or(|p| !self.reaches_through(placed, p, self.tolerance + slack))
    }

    /// The pose moved along the plane's normal onto the deepest place the check allows, and how
    /// far (m) it was moved; `None` where it does not reach through past the tolerance.
    pub fn lifted(&self, placed: &PlacedSuperquadric, plane: &Plane) -> Option<(PlacedSuperquadric, f64)> {
        let excess = self.penetration(placed, plane) - self.tolerance;
        if excess <= 0.0 {
            return None;
        }
        let mut out = *placed;
        // A micrometre more, so that rounding cannot leave it a hair too deep for the check.
        out.pose.translation.vector += plane.normal * (excess + 1e-6);
        Some((out, excess))
    }

    /// Whether the part stands as it may on the plane: an open container on its base or its rim
    /// (any closed part stands any way).
    pub fn stands(&self, placed: &PlacedSuperquadric, plane: &Plane) -> bool {
        let z = placed.pose.rotation * Vector3::z();
        !self.open || z.dot(&plane.normal).abs() >= MAX_REST_TILT.cos()
    }

    /// Whether the pose is possible for an object resting on or above the plane: it does not
    /// reach through it, and an open container stands on its base or its rim.
    pub fn allows(&self, space: &SearchSpace<'_>, placed: &PlacedSuperquadric) -> bool {
        space
            .plane
            .as_ref()
            .is_none_or(|p| self.stands(placed, p) && !self.reaches_through(placed, p, self.tolerance))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box and the first sample past the limit settle what the lowest sample would: on
    /// poses of every tilt and height about the plane, at depths from well above it to well
    /// through it.
    #[test]
    fn reaching_through_is_the_penetration_past_the_depth() {
        use nalgebra::{Isometry3, Vector3};
        use rand::{RngExt, SeedableRng};
        let shape = Superquadric::new([0.06, 0.05, 0.02], 0.4, 0.8, 0.3, -0.2).unwrap();
        let check = PlaneCheck::new(&shape, 0.001, false);
        let plane = Plane {
            normal: Vector3::new(0.1, -0.05, 1.0).normalize(),
            d: -0.7,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut through, mut clear) = (0, 0);
        for _ in 0..2000 {
            let pose = Isometry3::new(
                Vector3::new(0.8, 0.1, 0.7 + rng.random_range(-0.08..0.1)),
                Vector3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
            );
            let placed = PlacedSuperquadric::new(shape, pose);
            let depth = rng.random_range(-0.02..0.05);
            let deeper = check.penetration(&placed, &plane) > depth;
            assert_eq!(
                check.reaches_through(&placed, &plane, depth),
                deeper,
                "{pose:?} at {depth}"
            );
            if deeper { through += 1 } else { clear += 1 }
        }
        assert!(through > 300 && clear > 300, "{through} through, {clear} clear");
    }

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
