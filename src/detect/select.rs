//! The selection stage: what the detector reports from its ranked, judged candidates, and in
//! which of the object's equivalent poses.

use super::report::Detection;
use crate::cloud::plane::Plane;
use crate::model::Model;
use crate::symmetry::Symmetry;
use nalgebra::Vector3;

/// A container standing on its rim shows only its outside, which a closed can of its size
/// shows as well: it is the weaker answer. Its confidence is held at this, and any container
/// found standing on its base, whose open top the sensor saw, is preferred to it.
pub const ON_RIM_CONFIDENCE: f64 = 0.5;

/// Flag each candidate of a model with an open part as standing on its base or on its rim (see
/// [`Detection::upright`]), and hold the confidence of those on their rims.
pub fn flag_upright(candidates: &mut [Detection], model: &Model, plane: &Plane) {
    for d in candidates {
        d.upright = upright(model, &d.pose, plane);
        if d.upright == Some(false) {
            d.confidence = d.confidence.min(ON_RIM_CONFIDENCE);
        }
    }
}

/// For a model with an open part, whether the object at `pose` stands on its base (its opening
/// faces up from the plane); `None` for a model without one.
pub fn upright(model: &Model, pose: &nalgebra::Isometry3<f64>, plane: &Plane) -> Option<bool> {
    let opening = model.parts.iter().find(|p| p.open)?;
    Some((pose.rotation * opening.pose_in_object.rotation * Vector3::z()).dot(&plane.normal) > 0.0)
}

/// With `all`, every accepted instance that does not overlap a better one (centres closer than
/// `max_size`), those standing on their base before those on their rim; with `overlapping` too,
/// every accepted instance in that order. Otherwise the voting
/// winner, unless a lower-ranked candidate passes the acceptance test and the winner does not
/// (voting is relative; acceptance is absolute), and a container on its base before one on its
/// rim.
pub fn select(mut candidates: Vec<Detection>, all: bool, overlapping: bool, max_size: f64) -> Vec<Detection> {
    // Stable: the ranking holds within each kind.
    candidates.sort_by_key(|d| d.upright == Some(false));
    if all {
        candidates.retain(|d| d.found);
        if !overlapping {
            candidates = distinct(candidates, max_size, |_| true);
        }
        candidates
    } else {
        match candidates.iter().position(|d| d.found) {
            Some(k) => vec![candidates.swap_remove(k)],
            None => candidates.into_iter().take(1).collect(),
        }
    }
}

/// The instances of `candidates` (best first) that `keep` accepts and that do not overlap a
/// better one it accepted (centres closer than `max_size`); `keep` is asked only of those that
/// would be kept.
pub fn distinct(
    candidates: Vec<Detection>,
    max_size: f64,
    mut keep: impl FnMut(&mut Detection) -> bool,
) -> Vec<Detection> {
    let mut kept: Vec<Detection> = Vec::new();
    for mut d in candidates {
        let c = d.pose.translation.vector;
        if kept.iter().all(|k| (k.pose.translation.vector - c).norm() > max_size) && keep(&mut d) {
            kept.push(d);
        }
    }
    kept
}

/// How close (m) the centres of two instances of `model` may be for them to be one: the largest
/// size of any of its parts.
pub fn overlap_distance(model: &Model) -> f64 {
    model.parts.iter().map(|p| p.shape.max_size()).fold(0.0, f64::max)
}

/// Report the equivalent pose that stands on the plane (see `Symmetry::canonical_up`). The
/// symmetry search samples the model, so it is done only for a pose that leans away from the
/// plane's normal, and once for each model (`Symmetry::cached`).
pub fn stand_on_plane(detections: &mut [Detection], model: &Model, plane: &Plane) {
    let up = plane.normal;
    let mut symmetry = None;
    for d in detections {
        if (d.pose.rotation * Vector3::z()).dot(&up) < 0.0 {
            let s = symmetry.get_or_insert_with(|| Symmetry::cached(model));
            d.pose.rotation = s.canonical_up(&d.pose.rotation, &up);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3};

    fn at(x: f64) -> Detection {
        Detection {
            found: true,
            confidence: 1.0,
            pose: Isometry3::from_parts(Translation3::new(x, 0.0, 0.0), Default::default()),
            parts: Vec::new(),
            connection_errors: Vec::new(),
            upright: None,
            short_of_coverage: None,
            colour: None,
        }
    }

    /// An instance the caller turns away does not hide one that overlaps it; one it keeps does;
    /// the caller is asked only of those that would be kept.
    #[test]
    fn a_refused_instance_does_not_hide_the_one_it_overlaps() {
        let xs = [0.0, 0.05, 0.1, 0.5];
        let everything = distinct(xs.iter().map(|&x| at(x)).collect(), 0.2, |_| true);
        let kept: Vec<f64> = everything.iter().map(|d| d.pose.translation.x).collect();
        assert_eq!(kept, [0.0, 0.5]);
        let mut asked = Vec::new();
        let first_refused = distinct(xs.iter().map(|&x| at(x)).collect(), 0.2, |d| {
            asked.push(d.pose.translation.x);
            d.pose.translation.x != 0.0
        });
        let kept: Vec<f64> = first_refused.iter().map(|d| d.pose.translation.x).collect();
        assert_eq!(kept, [0.05, 0.5]);
        assert_eq!(asked, [0.0, 0.05, 0.5], "the one overlapping a kept one is not asked");
    }

    /// With `overlapping`, every accepted instance comes back, best first; without, the
    /// overlapping ones are set aside.
    #[test]
    fn overlapping_instances_come_back_only_when_asked_for() {
        let mut not_found = at(0.3);
        not_found.found = false;
        let candidates = || vec![at(0.0), at(0.05), not_found.clone(), at(0.5)];
        assert_eq!(select(candidates(), true, true, 0.2).len(), 3);
        assert_eq!(select(candidates(), true, false, 0.2).len(), 2);
        assert_eq!(select(candidates(), false, true, 0.2).len(), 1);
    }
}
