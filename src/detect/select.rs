//! The selection stage: what the detector reports from its ranked, judged candidates, and in
//! which of the object's equivalent poses.

use super::report::Detection;
use crate::cloud::plane::Plane;
use crate::model::Model;
use crate::symmetry::Symmetry;
use nalgebra::Vector3;

/// With `all`, every accepted instance that does not overlap a better one (centres closer than
/// `max_size`). Otherwise the voting winner, unless a lower-ranked candidate passes the
/// acceptance test and the winner does not (voting is relative; acceptance is absolute).
pub fn select(mut candidates: Vec<Detection>, all: bool, max_size: f64) -> Vec<Detection> {
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
/// plane's normal.
pub fn stand_on_plane(detections: &mut [Detection], model: &Model, plane: &Plane) {
    let up = plane.normal;
    let mut symmetry = None;
    let opening = model.parts.iter().find(|p| p.open);
    for d in detections {
        if (d.pose.rotation * Vector3::z()).dot(&up) < 0.0 {
            let s = symmetry.get_or_insert_with(|| Symmetry::of(model));
            d.pose.rotation = s.canonical_up(&d.pose.rotation, &up);
        }
        // Opening turned to the plane's side: the container stands on its rim.
        d.upright = opening.map(|p| (d.pose.rotation * p.pose_in_object.rotation * Vector3::z()).dot(&up) > 0.0);
    }
}
