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
/// `max_size`), those standing on their base before those on their rim. Otherwise the voting
/// winner, unless a lower-ranked candidate passes the acceptance test and the winner does not
/// (voting is relative; acceptance is absolute), and a container on its base before one on its
/// rim.
pub fn select(mut candidates: Vec<Detection>, all: bool, max_size: f64) -> Vec<Detection> {
    // Stable: the ranking holds within each kind.
    candidates.sort_by_key(|d| d.upright == Some(false));
    if all {
        let mut kept: Vec<Detection> = Vec::new();
        for d in candidates {
            if !d.found {
                continue;
            }
            let c = d.pose.translation.vector;
            if kept.iter().all(|k| (k.pose.translation.vector - c).norm() > max_size) {
                kept.push(d);
            }
        }
        kept
    } else {
        match candidates.iter().position(|d| d.found) {
            Some(k) => vec![candidates.swap_remove(k)],
            None => candidates.into_iter().take(1).collect(),
        }
    }
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
