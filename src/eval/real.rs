//! Scoring the detector on real scans labelled by object class: one `labels.json` entry a scene,
//! `{"scene", "objects": [{"class", "centroid", "visible", "upright", ...}]}` (the format of the
//! mOSD labels, `docs/DETECTOR.md`). The labels are for scoring only: the detector never sees
//! them.
//!
//! A found answer is matched to the labelled object whose centroid is nearest, within
//! [`MATCH_RADIUS_M`]. It is right once per object of the asked class standing as labelled; a
//! second answer on the same object, an answer on anything else (another kind of bowl included)
//! or on nothing labelled, and one whose upright flag is wrong are false answers.

use crate::spec::SpecError;
use nalgebra::Point3;
use serde::Deserialize;
use std::path::Path;

/// A detection counts on an object whose labelled centroid is this close (m).
pub const MATCH_RADIUS_M: f64 = 0.05;

/// One scene's labels.
#[derive(Debug, Clone, Deserialize)]
pub struct SceneLabels {
    /// The cloud's file stem (`learn0` for `learn0.pcd`).
    pub scene: String,
    pub objects: Vec<LabelledObject>,
}

/// One labelled object.
#[derive(Debug, Clone, Deserialize)]
pub struct LabelledObject {
    /// `mug`, `white_bowl`, `other_bowl`, `other`, ...
    pub class: String,
    /// A few words, for the report.
    #[serde(default)]
    pub what: String,
    /// The mean of its labelled points, in the cloud's frame (m).
    pub centroid: [f64; 3],
    /// `full`, `partial`, `occluded`.
    #[serde(default)]
    pub visible: Option<String>,
    /// False when upside-down; absent: upright.
    #[serde(default)]
    pub upright: Option<bool>,
}

impl LabelledObject {
    pub fn is_upright(&self) -> bool {
        self.upright.unwrap_or(true)
    }
}

/// Reads a labels file, refusing one whose centroids are not finite (naming the scene and the
/// object).
pub fn read_labels(path: &Path) -> Result<Vec<SceneLabels>, SpecError> {
    let text = crate::spec::read_text(path)?;
    let scenes: Vec<SceneLabels> = serde_json::from_str(&text).map_err(|e| SpecError::Syntax {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    for s in &scenes {
        if let Some(k) = s.objects.iter().position(|o| o.centroid.iter().any(|c| !c.is_finite())) {
            return Err(SpecError::invalid(
                path,
                format!("{}.objects[{k}].centroid", s.scene),
                "not finite",
            ));
        }
    }
    Ok(scenes)
}

/// A found answer of the detector: where, and whether it stands upright on the support plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answer {
    pub position: Point3<f64>,
    pub upright: bool,
}

/// Why an answer is false.
#[derive(Debug, Clone, PartialEq)]
pub enum FalseAnswer {
    /// No labelled object within the match radius.
    Nothing,
    /// On an object of another class (its index).
    OtherObject(usize),
    /// A second answer on an object already found.
    Second(usize),
    /// On an object of the class, but upside-down where it stands upright, or the reverse.
    WrongUpright(usize),
}

/// One scene's score for one class.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneScore {
    /// For each labelled object of the class (index into the scene's objects): found.
    pub targets: Vec<(usize, bool)>,
    /// The false answers: the answer's index and why.
    pub false_answers: Vec<(usize, FalseAnswer)>,
}

/// Scores the answers (best first) of one scene against its labels for `class`.
pub fn score_scene(objects: &[LabelledObject], class: &str, answers: &[Answer]) -> SceneScore {
    let mut found = vec![false; objects.len()];
    let mut false_answers = Vec::new();
    for (k, a) in answers.iter().enumerate() {
        let nearest = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (i, (Point3::from(o.centroid) - a.position).norm()))
            .filter(|(_, d)| *d <= MATCH_RADIUS_M)
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .map(|(i, _)| i);
        let verdict = match nearest {
            None => Some(FalseAnswer::Nothing),
            Some(i) if objects[i].class != class => Some(FalseAnswer::OtherObject(i)),
            Some(i) if objects[i].is_upright() != a.upright => Some(FalseAnswer::WrongUpright(i)),
            Some(i) if found[i] => Some(FalseAnswer::Second(i)),
            Some(i) => {
                found[i] = true;
                None
            }
        };
        if let Some(v) = verdict {
            false_answers.push((k, v));
        }
    }
    let targets = objects
        .iter()
        .enumerate()
        .filter(|(_, o)| o.class == class)
        .map(|(i, _)| (i, found[i]))
        .collect();
    SceneScore { targets, false_answers }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(class: &str, centroid: [f64; 3], upright: Option<bool>) -> LabelledObject {
        LabelledObject {
            class: class.into(),
            what: String::new(),
            centroid,
            visible: Some("full".into()),
            upright,
        }
    }

    fn answer(x: f64, upright: bool) -> Answer {
        Answer {
            position: Point3::new(x, 0.0, 1.0),
            upright,
        }
    }

    #[test]
    fn an_answer_is_right_once_per_object_of_the_class() {
        let objects = [
            object("mug", [0.0, 0.0, 1.0], None),
            object("other", [0.3, 0.0, 1.0], None),
            object("mug", [0.6, 0.0, 1.0], Some(false)),
            object("white_bowl", [0.9, 0.0, 1.0], None),
        ];
        let answers = [
            answer(0.02, true),  // right: the first mug
            answer(-0.01, true), // a second answer on it
            answer(0.31, true),  // on the tea box
            answer(0.6, true),   // the upside-down mug taken as upright
            answer(0.9, true),   // on a bowl
            answer(1.5, true),   // on nothing
        ];
        let s = score_scene(&objects, "mug", &answers);
        assert_eq!(s.targets, vec![(0, true), (2, false)]);
        assert_eq!(
            s.false_answers,
            vec![
                (1, FalseAnswer::Second(0)),
                (2, FalseAnswer::OtherObject(1)),
                (3, FalseAnswer::WrongUpright(2)),
                (4, FalseAnswer::OtherObject(3)),
                (5, FalseAnswer::Nothing),
            ]
        );
        // Flagged upside-down, it is found.
        let s = score_scene(&objects, "mug", &[answer(0.6, false)]);
        assert_eq!(s.targets, vec![(0, false), (2, true)]);
        assert!(s.false_answers.is_empty());
    }

    #[test]
    fn the_nearest_labelled_object_takes_the_answer() {
        // A mug 4 cm off and a box 2 cm off: the answer lies on the box.
        let objects = [
            object("mug", [0.04, 0.0, 1.0], None),
            object("other", [-0.02, 0.0, 1.0], None),
        ];
        let s = score_scene(&objects, "mug", &[answer(0.0, true)]);
        assert_eq!(s.targets, vec![(0, false)]);
        assert_eq!(s.false_answers, vec![(0, FalseAnswer::OtherObject(1))]);
    }

    #[test]
    fn a_labels_file_with_a_bad_centroid_is_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("sqscan-labels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("labels.json");
        std::fs::write(
            &path,
            r#"[{"scene": "s1", "objects": [{"class": "mug", "centroid": [0, 0, 1e999]}]}]"#,
        )
        .unwrap();
        let e = read_labels(&path).unwrap_err().to_string();
        assert!(e.contains("labels.json"), "{e}");
        std::fs::write(&path, r#"[{"scene": "s1", "objects": [{"class": "mug"}]}]"#).unwrap();
        let e = read_labels(&path).unwrap_err().to_string();
        assert!(e.contains("centroid"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
