//! The detector's JSON answer, shared by `sqscan detect` and the daemon: typed, so the daemon's
//! protocol schema (`docs/protocol.schema.json`) is generated from the same structs that write it.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{Detection, Report};
use crate::pose::PoseJson;

/// Round to a micrometre / microradian: more digits are noise and make diffs unreadable.
fn r6(v: f64) -> f64 {
    if v.is_finite() { (v * 1e6).round() / 1e6 } else { v }
}

/// A finite value rounded, or `None` (JSON `null`) for a score that could not be computed.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then(|| r6(v))
}

fn pose(p: &nalgebra::Isometry3<f64>) -> PoseJson {
    let j = PoseJson::from(p);
    PoseJson {
        position: j.position.map(r6),
        orientation: j.orientation.map(r6),
    }
}

/// One part of a detection and its votes (`docs/DETECTOR.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PartJson {
    pub name: String,
    /// Whether this part was placed.
    pub found: bool,
    pub pose: Option<PoseJson>,
    /// Mean fit residual of the part's points (`null` when it could not be computed).
    #[serde(rename = "M")]
    pub m: Option<f64>,
    /// Points on the part's surface.
    #[serde(rename = "S")]
    pub s: usize,
    /// Points inside the part, where the sensor could not have seen through it.
    #[serde(rename = "I")]
    pub i: usize,
    /// Share of the part's visible surface that holds points, in [0, 1].
    pub coverage: f64,
    /// RMS distance of its points from the surface (m).
    pub rms_m: Option<f64>,
}

/// How well two connected parts meet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConnectionJson {
    pub angle_error_rad: Option<f64>,
    pub distance_error_m: Option<f64>,
}

/// One candidate: accepted (`found`) or the most similar thing refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectionJson {
    pub found: bool,
    /// In [0, 1].
    pub confidence: f64,
    /// `null` when the scene held nothing to fit.
    pub pose: Option<PoseJson>,
    pub parts: Vec<PartJson>,
    /// For models with an open part: standing on its base (`true`) or on its rim.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upright: Option<bool>,
    /// For compound models: how each connection of the model is met.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub connections: Vec<ConnectionJson>,
    /// The share of the model's colours that the points on the found surface hold (0 to 1),
    /// where the model and the cloud have colours; below 0.35 the object is not found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<f64>,
    /// Where a parallel gripper can take the object, best first (`docs/GRASPS.md`); only when
    /// asked for, and only for a found object.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grasps: Vec<GraspJson>,
}

/// One grasp: the pose of the point midway between the pads (x closing, z approach).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GraspJson {
    /// The part taken.
    pub part: String,
    /// `across` (the pads on opposite sides of the part) or `rim` (across an open container's
    /// wall, one pad inside).
    pub kind: String,
    pub pose: PoseJson,
    /// Distance between the contacts (m).
    pub opening_m: f64,
    /// Where the pads touch the object (the fitted surface, or the measured one where the
    /// sensor saw it under the pads), the +x pad's first.
    pub contacts: [[f64; 3]; 2],
    /// Where the gripper comes from, open, along the approach.
    pub pregrasp: PoseJson,
    /// Lower is better.
    pub cost: f64,
}

/// A grasp in JSON, its part named `part`.
pub fn grasp_json(part: &str, g: &crate::grasp::Grasp) -> GraspJson {
    GraspJson {
        part: part.to_string(),
        kind: g.kind.name().into(),
        pose: pose(&g.pose),
        opening_m: r6(g.opening),
        contacts: g.contacts.map(|c| [r6(c.x), r6(c.y), r6(c.z)]),
        pregrasp: pose(&g.pregrasp),
        cost: r6(g.cost),
    }
}

/// Either every accepted instance (`all`), or the best candidate's fields at the top level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Answer {
    All {
        found: bool,
        detections: Vec<DetectionJson>,
    },
    Best(DetectionJson),
}

/// Time spent per stage (ms).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct TimingJson {
    pub plane: f64,
    pub search: f64,
    pub verify: f64,
    pub total: f64,
}

/// The whole answer of one detection run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ReportJson {
    pub object: String,
    #[serde(flatten)]
    pub answer: Answer,
    /// The dominant plane `[a, b, c, d]` (`a x + b y + c z + d = 0`, unit normal), if one was found.
    pub plane: Option<[f64; 4]>,
    /// Points in the cloud given.
    pub points: usize,
    /// Points left for the search after plane removal and cropping (rows far denser than 2 mm
    /// thinned first).
    pub scene_points: usize,
    pub timing_ms: TimingJson,
}

/// One detection as `{"found","confidence","pose","parts":[{"name","pose","M","S","I",...}]}`.
pub fn detection_json(d: &Detection) -> DetectionJson {
    DetectionJson {
        found: d.found,
        confidence: r6(d.confidence),
        pose: Some(pose(&d.pose)),
        parts: d
            .parts
            .iter()
            .map(|p| PartJson {
                name: p.name.clone(),
                found: p.placed.is_some(),
                pose: p.placed.map(|q| pose(&q.pose)),
                m: finite(p.scores.m),
                s: p.scores.s,
                i: p.scores.i,
                coverage: r6(p.scores.coverage),
                rms_m: finite(p.scores.rms),
            })
            .collect(),
        upright: d.upright,
        connections: d
            .connection_errors
            .iter()
            .map(|(a, dd)| ConnectionJson {
                angle_error_rad: finite(*a),
                distance_error_m: finite(*dd),
            })
            .collect(),
        colour: d.colour.map(|c| (c * 1e3).round() / 1e3),
        grasps: Vec::new(),
    }
}

/// The whole answer. With `all`, `"detections"` lists every instance; otherwise the best
/// candidate's fields are at the top level (`"found": false` with the most similar thing's pose
/// when the acceptance test refused it, and `"pose": null` when nothing could be fitted).
pub fn report_json(r: &Report, all: bool) -> ReportJson {
    let answer = if all {
        Answer::All {
            found: !r.detections.is_empty(),
            detections: r.detections.iter().map(detection_json).collect(),
        }
    } else {
        Answer::Best(match r.detections.first() {
            Some(d) => detection_json(d),
            None => DetectionJson {
                found: false,
                confidence: 0.0,
                pose: None,
                parts: Vec::new(),
                upright: None,
                connections: Vec::new(),
                colour: None,
                grasps: Vec::new(),
            },
        })
    };
    ReportJson {
        object: r.object.clone(),
        answer,
        plane: r.plane.as_ref().map(|p| p.coefficients().map(r6)),
        points: r.points,
        scene_points: r.scene_points,
        timing_ms: TimingJson {
            plane: r6(r.timing.plane_ms),
            search: r6(r.timing.search_ms),
            verify: r6(r.timing.verify_ms),
            total: r6(r.timing.total_ms),
        },
    }
}

/// Give each found detection of `json` (made by [`report_json`] from `r`) up to `max` grasps of
/// `gripper`, checked against `cloud` (the points `r` was detected in, seen from `viewpoint`)
/// and `r`'s plane.
pub fn add_grasps(
    json: &mut ReportJson,
    r: &Report,
    model: &crate::model::Model,
    cloud: &[[f32; 3]],
    viewpoint: Option<nalgebra::Point3<f64>>,
    gripper: &crate::grasp::Gripper,
    max: usize,
) {
    let detections: Vec<&mut DetectionJson> = match &mut json.answer {
        Answer::All { detections, .. } => detections.iter_mut().collect(),
        Answer::Best(d) => vec![d],
    };
    for (dj, d) in detections.into_iter().zip(&r.detections) {
        if !d.found {
            continue;
        }
        let (parts, names): (Vec<crate::grasp::Part>, Vec<&str>) = d.grasp_parts(model).into_iter().unzip();
        dj.grasps = crate::grasp::plan(&parts, cloud, r.plane.as_ref(), viewpoint, gripper, max)
            .iter()
            .map(|g| grasp_json(names[g.part], g))
            .collect();
    }
}
