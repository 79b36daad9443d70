//! What the detector answers: the detections with their parts and scores, the support plane and
//! the time each stage took. The `Display` impls are the one-line summaries the stages log at
//! `SQSCAN_LOG=debug`.

use super::verify::Scores;
use crate::cloud::plane::Plane;
use crate::geometry::PlacedSuperquadric;
use nalgebra::{Isometry3, Vector3};
use std::fmt;

/// One part of a detection.
#[derive(Debug, Clone)]
pub struct PartResult {
    pub name: String,
    /// The part's pose in the cloud's frame; `None` when a compound's part was not found.
    pub placed: Option<PlacedSuperquadric>,
    pub scores: Scores,
}

/// One detected instance.
#[derive(Debug, Clone)]
pub struct Detection {
    /// Whether the acceptance test says this is the object.
    pub found: bool,
    pub confidence: f64,
    /// The object's pose (its model frame) in the cloud's frame.
    pub pose: Isometry3<f64>,
    pub parts: Vec<PartResult>,
    /// For compounds: angle (rad) and distance (m) errors of each connection.
    pub connection_errors: Vec<(f64, f64)>,
    /// For a model with an open part, on a support plane: whether its opening faces up (false:
    /// it stands on its rim).
    pub upright: Option<bool>,
    /// The acceptance test failed on coverage alone, by no more than the surface that another
    /// object may hide: the least of its other margins; the free-space check decides (see
    /// [`super::accept::check_free_space`]).
    pub short_of_coverage: Option<f64>,
    /// The share of the model's colours that the points on the found surface hold, where both
    /// have colours ([`super::check_colour`]).
    pub colour: Option<f64>,
}

impl Detection {
    /// The parts placed (a compound's part may not be) as the grasp planner takes them, with
    /// their names; `model` is the model detected.
    pub fn grasp_parts<'a>(&'a self, model: &crate::model::Model) -> Vec<(crate::grasp::Part, &'a str)> {
        self.parts
            .iter()
            .zip(&model.parts)
            .filter_map(|(p, m)| {
                p.placed
                    .map(|placed| (crate::grasp::Part { placed, open: m.open }, p.name.as_str()))
            })
            .collect()
    }
}

/// Milliseconds spent in each stage.
#[derive(Debug, Clone, Copy, Default)]
pub struct Timing {
    /// Filtering the input and removing the plane.
    pub plane_ms: f64,
    /// Subsampling and indexing, the hypotheses and the compound parts' search.
    pub search_ms: f64,
    /// Scoring, the acceptance test and the free-space check along the lines of sight.
    pub verify_ms: f64,
    /// All of it, from the cloud to the answer.
    pub total_ms: f64,
}

/// What a detection run found.
#[derive(Debug, Clone)]
pub struct Report {
    pub object: String,
    /// The best candidate first; with `Params::all` every accepted instance. Empty when the scene
    /// held nothing to fit.
    pub detections: Vec<Detection>,
    pub plane: Option<Plane>,
    /// Finite input points.
    pub points: usize,
    /// Points left after plane removal and the range cut, of those the detector kept (a cloud
    /// whose rows are far denser than 2 mm is thinned along them first).
    pub scene_points: usize,
    pub timing: Timing,
}

impl Report {
    /// The best candidate if the acceptance test passed it.
    pub fn best_found(&self) -> Option<&Detection> {
        self.detections.first().filter(|d| d.found)
    }
}

/// A pose as its position and z axis (the axis of a part's symmetry and taper):
/// `pos (x y z) z (x y z)`.
pub(super) struct PoseText<'a>(pub &'a Isometry3<f64>);

impl fmt::Display for PoseText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = self.0.translation.vector;
        let z = self.0.rotation * Vector3::z();
        write!(
            f,
            "pos ({:.3} {:.3} {:.3}) z ({:.2} {:.2} {:.2})",
            t.x, t.y, t.z, z.x, z.y, z.z
        )
    }
}

/// The paper's criteria alone: `M .. S .. I ..`.
pub(super) struct VotesText<'a>(pub &'a Scores);

impl fmt::Display for VotesText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "M {:.4} S {} I {}", self.0.m, self.0.s, self.0.i)
    }
}

/// The connection errors of a compound: `A <deg> deg D <m>` for each connection.
pub(super) struct ConnectionText<'a>(pub &'a [(f64, f64)]);

impl fmt::Display for ConnectionText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (k, (a, d)) in self.0.iter().enumerate() {
            if k > 0 {
                f.write_str(" ")?;
            }
            write!(f, "A {:.1} deg D {:.3}", a.to_degrees(), d)?;
        }
        Ok(())
    }
}

/// `name pos (..) z (..) M .. S .. I .. cov ..`, or `name -` for a part not found.
impl fmt::Display for PartResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.placed {
            Some(q) => write!(f, "{} {} {}", self.name, PoseText(&q.pose), self.scores),
            None => write!(f, "{} -", self.name),
        }
    }
}

/// `found .. conf .. pos (..) z (..) [A .. D ..] | part | part ..`.
impl fmt::Display for Detection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "found {} conf {:.3} {}",
            self.found,
            self.confidence,
            PoseText(&self.pose)
        )?;
        if !self.connection_errors.is_empty() {
            write!(f, " {}", ConnectionText(&self.connection_errors))?;
        }
        for p in &self.parts {
            write!(f, " | {p}")?;
        }
        Ok(())
    }
}

/// Milliseconds since `t`, as the timings give them.
pub(super) fn ms(t: std::time::Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Superquadric;

    #[test]
    fn a_detection_logs_its_pose_connections_and_every_part_with_its_scores() {
        let shape = Superquadric::new([0.04, 0.04, 0.05], 0.3, 1.0, 0.0, 0.0).unwrap();
        let pose = Isometry3::translation(0.9, 0.2, 0.77);
        let d = Detection {
            found: true,
            confidence: 0.9391,
            pose,
            parts: vec![
                PartResult {
                    name: "body".into(),
                    placed: Some(PlacedSuperquadric::new(shape, pose)),
                    scores: Scores {
                        m: 0.07405,
                        s: 893,
                        i: 7,
                        coverage: 1.0,
                        rms: 0.00143,
                        surface_points: 969,
                        inside_points: 22,
                        shell_points: 40,
                        continued_points: 12,
                        faces: 2.5,
                        base_recess: None,
                        raised: Some((0.056, 240)),
                    },
                },
                PartResult {
                    name: "handle".into(),
                    placed: None,
                    scores: Scores::default(),
                },
            ],
            connection_errors: vec![(2.6f64.to_radians(), 0.004)],
            upright: None,
            short_of_coverage: None,
            colour: None,
        };
        assert_eq!(
            d.to_string(),
            "found true conf 0.939 pos (0.900 0.200 0.770) z (0.00 0.00 1.00) A 2.6 deg D 0.004 \
             | body pos (0.900 0.200 0.770) z (0.00 0.00 1.00) \
             M 0.0741 S 893 I 7 cov 1.00 rms 0.0014 surf 969 inside 22 shell 40 continued 12 faces 2.50 base - raised 56.0 mm on 240 | handle -"
        );
    }
}
