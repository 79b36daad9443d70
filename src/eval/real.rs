//! Scoring the detector on real scans labelled by object: one `labels.json` entry a scene,
//! `{"scene", "objects": [{"class", "identity", "pose", "support", "centroid", "visible",
//! "upright", ...}]}` (the format of the mOSD labels, `../shared/data/CATALOGUE.md`). The labels
//! are for scoring only: the detector never sees them.
//!
//! The rule, for a class (`mug`) or an identity (`biscuit_tin`, one physical object) alike: each
//! found answer, best first, is matched to the labelled object whose centroid is nearest to its
//! position. It is right when that object is an instance of what was asked, within
//! max(5 cm, half the object's largest size) of it, standing as labelled (for objects labelled
//! upright or not), and not yet claimed; neutral when that object is `unknown` or `mixed`, or is
//! the view the model was learned from; false otherwise: another object, nothing near, the wrong
//! way up, a second answer on the same instance. Recall is over the instances that are not
//! `occluded`, except the view the model was learned from.

use crate::spec::SpecError;
use nalgebra::Point3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The least match radius (m): an answer this close to an object's labelled centroid is on it
/// whatever its size.
pub const MATCH_RADIUS_M: f64 = 0.05;

/// One scene's labels.
#[derive(Debug, Clone, Deserialize)]
pub struct SceneLabels {
    /// The cloud's file stem (`learn0` for `learn0.pcd`).
    pub scene: String,
    pub objects: Vec<LabelledObject>,
}

/// One labelled object.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct LabelledObject {
    /// `mug`, `white_bowl`, `other_bowl`, `other`, ...
    pub class: String,
    /// Which physical object it is, the same in every scene; `unknown` where it could not be
    /// told, `mixed` where the group holds two objects.
    #[serde(default)]
    pub identity: Option<String>,
    /// The segment's group in the scene (what `sqscan learn --label` takes).
    #[serde(default)]
    pub group: Option<i64>,
    /// `standing`, `upside_down`, `lying`, `on_edge`, `flat`.
    #[serde(default)]
    pub pose: Option<String>,
    /// `table`, or what it rests on.
    #[serde(default)]
    pub support: Option<String>,
    /// A few words, for the report.
    #[serde(default)]
    pub what: String,
    /// The mean of its labelled points, in the cloud's frame (m).
    pub centroid: [f64; 3],
    /// `full`, `partial`, `occluded`.
    #[serde(default)]
    pub visible: Option<String>,
    /// For containers: false when upside-down.
    #[serde(default)]
    pub upright: Option<bool>,
    /// Its largest size (m), where the labels carry it (the simulator's do); otherwise the
    /// catalogue's.
    #[serde(default)]
    pub size: Option<f64>,
}

impl LabelledObject {
    pub fn is_upright(&self) -> bool {
        self.upright.unwrap_or(true)
    }

    /// The pose for the report: the label's, else what the upright flag says.
    pub fn pose_name(&self) -> String {
        match (&self.pose, self.upright) {
            (Some(p), _) => p.clone(),
            (None, Some(false)) => "upside_down".into(),
            (None, _) => "standing".into(),
        }
    }

    /// Resting on another object rather than on the table (or on nothing labelled).
    pub fn is_stacked(&self) -> bool {
        self.support.as_deref().is_some_and(|s| s != "table")
    }

    fn is_occluded(&self) -> bool {
        self.visible.as_deref() == Some("occluded")
    }

    /// An object nobody can say is or is not what was asked.
    fn is_undecided(&self) -> bool {
        matches!(self.identity.as_deref(), Some("unknown" | "mixed"))
    }
}

/// Reads a labels file, refusing one whose centroids or sizes are not finite (naming the scene
/// and the object).
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
        if let Some(k) = s
            .objects
            .iter()
            .position(|o| o.size.is_some_and(|v| !(v.is_finite() && v > 0.0)))
        {
            return Err(SpecError::invalid(
                path,
                format!("{}.objects[{k}].size", s.scene),
                "not a size > 0 m",
            ));
        }
    }
    Ok(scenes)
}

/// The objects' largest sizes (m) by identity, from a catalogue: a markdown table whose rows
/// start with the identity and hold the size as `LxWxH` in millimetres (`CATALOGUE.md`).
#[derive(Debug, Clone, Default)]
pub struct Catalogue {
    sizes: BTreeMap<String, f64>,
}

impl Catalogue {
    pub fn read(path: &Path) -> Result<Catalogue, SpecError> {
        let text = crate::spec::read_text(path)?;
        let sizes = Catalogue::parse(&text);
        if sizes.sizes.is_empty() {
            return Err(SpecError::invalid(
                path,
                "table",
                "no row with an identity and a size LxWxH in mm",
            ));
        }
        Ok(sizes)
    }

    /// The rows of every markdown table whose first cell is a name and one of whose cells is a
    /// size `LxWxH`; other lines are ignored.
    pub fn parse(text: &str) -> Catalogue {
        let mut sizes = BTreeMap::new();
        for line in text.lines() {
            let Some(row) = line.trim().strip_prefix('|') else {
                continue;
            };
            let cells: Vec<&str> = row.split('|').map(str::trim).collect();
            let Some(id) = cells.first().filter(|c| !c.is_empty() && !c.contains(' ')) else {
                continue;
            };
            let size = cells.iter().skip(1).find_map(|c| {
                let v: Vec<f64> = c.split('x').map(|d| d.parse::<f64>()).collect::<Result<_, _>>().ok()?;
                (v.len() == 3 && v.iter().all(|d| d.is_finite() && *d > 0.0))
                    .then(|| v.iter().copied().fold(0.0, f64::max) / 1000.0)
            });
            if let Some(s) = size {
                sizes.insert(id.to_string(), s);
            }
        }
        Catalogue { sizes }
    }

    /// The largest size (m) of an identity.
    pub fn size(&self, identity: &str) -> Option<f64> {
        self.sizes.get(identity).copied()
    }

    pub fn len(&self) -> usize {
        self.sizes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.sizes.is_empty()
    }
}

/// What a query asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// Any object of a labelled class (`mug`).
    Class(String),
    /// One physical object, wherever it is (`biscuit_tin`).
    Identity(String),
}

impl Target {
    fn is(&self, o: &LabelledObject) -> bool {
        match self {
            Target::Class(c) => &o.class == c,
            Target::Identity(id) => o.identity.as_deref() == Some(id),
        }
    }
}

/// How answers are scored: what was asked, the sizes that set each object's match radius, and
/// the view the model was learned from.
#[derive(Debug, Clone)]
pub struct Rule {
    pub target: Target,
    pub catalogue: Catalogue,
    /// The scene and group the model was learned from: an answer there is neutral, and the
    /// instance does not count in recall.
    pub learned_from: Option<(String, i64)>,
}

impl Rule {
    /// How close (m) to an object's centroid an answer is on it.
    pub fn radius(&self, o: &LabelledObject) -> f64 {
        let size = o
            .size
            .or_else(|| o.identity.as_deref().and_then(|id| self.catalogue.size(id)));
        size.map_or(MATCH_RADIUS_M, |s| MATCH_RADIUS_M.max(0.5 * s))
    }

    fn is_learned_view(&self, scene: &str, o: &LabelledObject) -> bool {
        self.learned_from
            .as_ref()
            .is_some_and(|(s, g)| s == scene && o.group == Some(*g))
    }
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
    /// The nearest labelled object (its index) is farther than its match radius, or there is
    /// none.
    Nothing,
    /// On an object that is not what was asked (its index).
    OtherObject(usize),
    /// A second answer on an instance already found.
    Second(usize),
    /// On an instance of what was asked, but upside-down where it stands upright, or the
    /// reverse.
    WrongUpright(usize),
}

/// One scene's score for one query.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneScore {
    /// For each instance counted in recall (index into the scene's objects): found.
    pub targets: Vec<(usize, bool)>,
    /// The false answers: the answer's index and why.
    pub false_answers: Vec<(usize, FalseAnswer)>,
    /// The neutral answers: the answer's index and the object's.
    pub neutral: Vec<(usize, usize)>,
}

/// Scores the answers (best first) of one scene against its labels.
pub fn score_scene(scene: &SceneLabels, rule: &Rule, answers: &[Answer]) -> SceneScore {
    let objects = &scene.objects;
    let mut found = vec![false; objects.len()];
    let mut score = SceneScore::default();
    for (k, a) in answers.iter().enumerate() {
        let nearest = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (i, (Point3::from(o.centroid) - a.position).norm()))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .filter(|&(i, d)| d <= rule.radius(&objects[i]))
            .map(|(i, _)| i);
        let verdict = match nearest {
            None => Some(FalseAnswer::Nothing),
            Some(i) if rule.is_learned_view(&scene.scene, &objects[i]) => {
                score.neutral.push((k, i));
                None
            }
            Some(i) if !rule.target.is(&objects[i]) => {
                if objects[i].is_undecided() {
                    score.neutral.push((k, i));
                    None
                } else {
                    Some(FalseAnswer::OtherObject(i))
                }
            }
            Some(i) if found[i] => Some(FalseAnswer::Second(i)),
            Some(i) if objects[i].upright.is_some_and(|u| u != a.upright) => Some(FalseAnswer::WrongUpright(i)),
            Some(i) => {
                found[i] = true;
                None
            }
        };
        if let Some(v) = verdict {
            score.false_answers.push((k, v));
        }
    }
    score.targets = objects
        .iter()
        .enumerate()
        .filter(|(_, o)| rule.target.is(o) && !o.is_occluded() && !rule.is_learned_view(&scene.scene, o))
        .map(|(i, _)| (i, found[i]))
        .collect();
    score
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(class: &str, identity: &str, centroid: [f64; 3], upright: Option<bool>) -> LabelledObject {
        LabelledObject {
            class: class.into(),
            identity: Some(identity.into()),
            centroid,
            visible: Some("full".into()),
            upright,
            ..Default::default()
        }
    }

    fn answer(x: f64, upright: bool) -> Answer {
        Answer {
            position: Point3::new(x, 0.0, 1.0),
            upright,
        }
    }

    fn rule(target: Target) -> Rule {
        Rule {
            target,
            catalogue: Catalogue::parse(
                "| identity | size mm |\n|---|---|\n| weetabix_box | 246x195x52 |\n| mug_plain | 115x101x76 |\n",
            ),
            learned_from: None,
        }
    }

    fn scene(objects: Vec<LabelledObject>) -> SceneLabels {
        SceneLabels {
            scene: "s".into(),
            objects,
        }
    }

    #[test]
    fn an_answer_is_right_once_per_object_of_the_class() {
        let s = scene(vec![
            object("mug", "mug_plain", [0.0, 0.0, 1.0], Some(true)),
            object("other", "tea_box", [0.3, 0.0, 1.0], None),
            object("mug", "mug_printed", [0.6, 0.0, 1.0], Some(false)),
            object("white_bowl", "white_bowl", [0.9, 0.0, 1.0], Some(true)),
        ]);
        let answers = [
            answer(0.02, true),  // right: the first mug
            answer(-0.01, true), // a second answer on it
            answer(0.31, true),  // on the tea box
            answer(0.6, true),   // the upside-down mug taken as upright
            answer(0.9, true),   // on a bowl
            answer(1.5, true),   // on nothing
        ];
        let r = rule(Target::Class("mug".into()));
        let sc = score_scene(&s, &r, &answers);
        assert_eq!(sc.targets, vec![(0, true), (2, false)]);
        assert_eq!(
            sc.false_answers,
            vec![
                (1, FalseAnswer::Second(0)),
                (2, FalseAnswer::OtherObject(1)),
                (3, FalseAnswer::WrongUpright(2)),
                (4, FalseAnswer::OtherObject(3)),
                (5, FalseAnswer::Nothing),
            ]
        );
        // Flagged upside-down, it is found.
        let sc = score_scene(&s, &r, &[answer(0.6, false)]);
        assert_eq!(sc.targets, vec![(0, false), (2, true)]);
        assert!(sc.false_answers.is_empty());
        // By identity, the printed mug alone is asked: the plain one is another object.
        let r = rule(Target::Identity("mug_printed".into()));
        let sc = score_scene(&s, &r, &[answer(0.6, false), answer(0.0, true)]);
        assert_eq!(sc.targets, vec![(2, true)]);
        assert_eq!(sc.false_answers, vec![(1, FalseAnswer::OtherObject(0))]);
    }

    #[test]
    fn the_nearest_labelled_object_takes_the_answer() {
        // A mug 4 cm off and a box 2 cm off: the answer lies on the box.
        let s = scene(vec![
            object("mug", "mug_plain", [0.04, 0.0, 1.0], None),
            object("other", "tea_box", [-0.02, 0.0, 1.0], None),
        ]);
        let sc = score_scene(&s, &rule(Target::Class("mug".into())), &[answer(0.0, true)]);
        assert_eq!(sc.targets, vec![(0, false)]);
        assert_eq!(sc.false_answers, vec![(0, FalseAnswer::OtherObject(1))]);
    }

    /// The match radius is half the object's largest size, at least 5 cm: an answer 9 cm from
    /// the centroid of a 246 mm box's visible side is on it; 9 cm from a mug's, on nothing.
    #[test]
    fn the_match_radius_grows_with_the_object() {
        let r = rule(Target::Identity("weetabix_box".into()));
        let s = scene(vec![object("other", "weetabix_box", [0.0, 0.0, 1.0], None)]);
        assert_eq!(score_scene(&s, &r, &[answer(0.09, true)]).targets, vec![(0, true)]);
        assert_eq!(
            score_scene(&s, &r, &[answer(0.13, true)]).false_answers,
            vec![(0, FalseAnswer::Nothing)]
        );
        let r = rule(Target::Identity("mug_plain".into()));
        let s = scene(vec![object("mug", "mug_plain", [0.0, 0.0, 1.0], None)]);
        assert_eq!(score_scene(&s, &r, &[answer(0.057, true)]).targets, vec![(0, true)]);
        assert_eq!(
            score_scene(&s, &r, &[answer(0.062, true)]).false_answers,
            vec![(0, FalseAnswer::Nothing)]
        );
        // A size in the labels wins over the catalogue's.
        let mut o = object("mug", "mug_plain", [0.0, 0.0, 1.0], None);
        o.size = Some(0.3);
        assert_eq!(
            score_scene(&scene(vec![o]), &r, &[answer(0.14, true)]).targets,
            vec![(0, true)]
        );
    }

    /// Answers on an `unknown` or `mixed` object, or on the view the model was learned from, are
    /// neither right nor false; occluded instances and the learned view are not in recall.
    #[test]
    fn undecided_objects_and_the_learned_view_are_neutral() {
        let mut learned = object("other", "tea_box", [0.0, 0.0, 1.0], None);
        learned.group = Some(2);
        let mut hidden = object("other", "tea_box", [0.3, 0.0, 1.0], None);
        hidden.visible = Some("occluded".into());
        let s = scene(vec![
            learned,
            hidden,
            object("other", "unknown", [0.6, 0.0, 1.0], None),
            object("other", "mixed", [0.9, 0.0, 1.0], None),
            object("other", "tea_box", [1.2, 0.0, 1.0], None),
        ]);
        let mut r = rule(Target::Identity("tea_box".into()));
        r.learned_from = Some(("s".into(), 2));
        let answers = [
            answer(0.0, true),
            answer(0.3, true),
            answer(0.6, true),
            answer(0.9, true),
        ];
        let sc = score_scene(&s, &r, &answers);
        assert_eq!(sc.targets, vec![(4, false)]);
        assert!(sc.false_answers.is_empty(), "{sc:?}");
        assert_eq!(sc.neutral, vec![(0, 0), (2, 2), (3, 3)]);
    }

    #[test]
    fn a_catalogue_gives_each_identity_its_largest_size() {
        let c = Catalogue::parse(
            "| identity | what | shape | size mm (best view) |\n|---|---|---|---|\n\
             | gittis_box | muesli box | box | 187x137x50 |\n| cd | CD lying flat | flat | 108x59x7 |\n\
             | not a row | x | y | 1x2x3 |\nsome text | tea_box | 1x1x1\n",
        );
        assert_eq!(c.len(), 2);
        assert!((c.size("gittis_box").unwrap() - 0.187).abs() < 1e-12);
        assert!((c.size("cd").unwrap() - 0.108).abs() < 1e-12);
        assert_eq!(c.size("tea_box"), None);
    }

    #[test]
    fn a_labels_file_with_a_bad_centroid_or_size_is_refused_by_name() {
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
        std::fs::write(
            &path,
            r#"[{"scene": "s1", "objects": [{"class": "mug", "centroid": [0, 0, 1], "size": -1}]}]"#,
        )
        .unwrap();
        let e = read_labels(&path).unwrap_err().to_string();
        assert!(e.contains("s1.objects[0].size"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
