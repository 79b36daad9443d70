//! The detector's JSON answer, shared by `sqscan detect` and the daemon.

use super::{Detection, Report};
use crate::pose::PoseJson;
use serde_json::{Value, json};

/// Round to a micrometre / microradian: more digits are noise and make diffs unreadable.
fn r6(v: f64) -> f64 {
    if v.is_finite() { (v * 1e6).round() / 1e6 } else { v }
}

fn pose(p: &nalgebra::Isometry3<f64>) -> Value {
    let j = PoseJson::from(p);
    json!({"position": j.position.map(r6), "orientation": j.orientation.map(r6)})
}

/// One detection as `{"found","confidence","pose","parts":[{"name","pose","M","S","I",...}]}`.
pub fn detection_json(d: &Detection) -> Value {
    let parts: Vec<Value> = d
        .parts
        .iter()
        .map(|p| {
            json!({
                "name": p.name,
                "found": p.placed.is_some(),
                "pose": p.placed.map(|q| pose(&q.pose)),
                "M": if p.scores.m.is_finite() { json!(r6(p.scores.m)) } else { Value::Null },
                "S": p.scores.s,
                "I": p.scores.i,
                "coverage": r6(p.scores.coverage),
                "rms_m": if p.scores.rms.is_finite() { json!(r6(p.scores.rms)) } else { Value::Null },
            })
        })
        .collect();
    let mut v = json!({
        "found": d.found,
        "confidence": r6(d.confidence),
        "pose": pose(&d.pose),
        "parts": parts,
    });
    if let Some(up) = d.upright {
        v["upright"] = json!(up);
    }
    if !d.connection_errors.is_empty() {
        v["connections"] = d
            .connection_errors
            .iter()
            .map(|(a, dd)| {
                json!({"angle_error_rad": if a.is_finite() { json!(r6(*a)) } else { Value::Null },
                                  "distance_error_m": if dd.is_finite() { json!(r6(*dd)) } else { Value::Null }})
            })
            .collect();
    }
    v
}

/// The whole answer. With `all`, `"detections"` lists every instance; otherwise the best
/// candidate's fields are at the top level (`"found": false` with the most similar thing's pose
/// when the acceptance test refused it, and no pose at all when nothing could be fitted).
pub fn report_json(r: &Report, all: bool) -> Value {
    let mut v = if all {
        json!({"object": r.object, "found": !r.detections.is_empty(),
               "detections": r.detections.iter().map(detection_json).collect::<Vec<_>>()})
    } else {
        match r.detections.first() {
            Some(d) => {
                let mut v = detection_json(d);
                v["object"] = json!(r.object);
                v
            }
            None => json!({"object": r.object, "found": false, "confidence": 0.0, "pose": null, "parts": []}),
        }
    };
    v["plane"] = match &r.plane {
        Some(p) => json!(p.coefficients().map(r6)),
        None => Value::Null,
    };
    v["points"] = json!(r.points);
    v["scene_points"] = json!(r.scene_points);
    v["timing_ms"] = json!({
        "plane": r6(r.timing.plane_ms), "search": r6(r.timing.search_ms),
        "verify": r6(r.timing.verify_ms), "total": r6(r.timing.total_ms)
    });
    v
}
