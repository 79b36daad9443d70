//! `sqscan eval-real`: the detector on real scans labelled by object: recall (by pose and by
//! support), false answers and time per query, with the misses and false answers by scene. A
//! query asks for a class of objects or for one physical object (an identity); both are scored
//! by the same rule (`sqscan::eval::real`).

use crate::detect::params_for;
use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::{Value, json};
use sqscan::cloud;
use sqscan::detect;
use sqscan::eval::median_p95;
use sqscan::eval::real::{
    Answer, Catalogue, FalseAnswer, LabelledObject, Rule, SceneLabels, SceneScore, Target, read_labels, score_scene,
};
use sqscan::grasp::{Gripper, Part, Swept, plan};
use sqscan::model::Model;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Args)]
#[command(group(clap::ArgGroup::new("asked").required(true).args(["class", "identity"])))]
pub struct EvalRealArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Labels file (JSON: one entry a scene, its objects with class, identity, pose, support,
    /// centroid, visible, upright)
    #[arg(long, value_name = "FILE.json")]
    labels: PathBuf,
    /// Directory of the scenes' clouds (SCENE.pcd for each labelled scene)
    #[arg(long, value_name = "DIR")]
    clouds: PathBuf,
    /// Model name (looked up in the models directory) or model file
    #[arg(long)]
    model: String,
    /// The labelled class the model should find (e.g. mug, white_bowl)
    #[arg(long)]
    class: Option<String>,
    /// The labelled identity (one physical object) the model should find (e.g. biscuit_tin)
    #[arg(long)]
    identity: Option<String>,
    /// The objects' sizes by identity, a markdown table with LxWxH in mm (an answer is on an
    /// object within max(5 cm, half its largest size)) [default: CATALOGUE.md in the labels
    /// file's directory or its parent, where there is one]
    #[arg(long, value_name = "FILE.md")]
    catalogue: Option<PathBuf>,
    /// The view the model was learned from, SCENE:GROUP: answers there are neutral and it is
    /// not counted in recall
    #[arg(long, value_name = "SCENE:GROUP", value_parser = parse_learned_from)]
    learned_from: Option<(String, i64)>,
    /// Seed of every random choice of the search
    #[arg(long, default_value_t = 5)]
    seed: u64,
    /// Ignore points farther than this from the viewpoint (m)
    #[arg(long, value_name = "M")]
    max_range: Option<f64>,
    /// Print one JSON object instead of the text report
    #[arg(long)]
    json: bool,
    /// Do not check a found object's colours against the model's (where both have colours)
    #[arg(long)]
    ignore_colour: bool,
    /// Plan grasps for every right answer and check the first against
    /// the labels: how many found objects get a grasp, how many first grasps sweep no
    /// point that is not the object's, and of those without, how many have one that a
    /// brute-force sampler over the fit finds
    #[arg(long)]
    grasps: bool,
    /// The gripper's settings for --grasps: a TOML file of the [gripper] table's keys
    /// [default: a Robotiq 2F-85-class gripper]
    #[arg(long, value_name = "GRIPPER.toml", requires = "grasps")]
    gripper: Option<PathBuf>,
}

fn parse_learned_from(s: &str) -> Result<(String, i64), String> {
    let (scene, group) = s
        .rsplit_once(':')
        .ok_or_else(|| format!("{s:?}: give SCENE:GROUP, e.g. learn36:2"))?;
    let group = group
        .parse()
        .map_err(|_| format!("{s:?}: the group {group:?} is not a whole number"))?;
    if scene.is_empty() {
        return Err(format!("{s:?}: no scene before the colon"));
    }
    Ok((scene.to_string(), group))
}

/// The catalogue asked for, else the one beside the labels, else none.
fn catalogue(a: &EvalRealArgs) -> Result<(Catalogue, Option<PathBuf>)> {
    if let Some(p) = &a.catalogue {
        return Ok((Catalogue::read(p)?, Some(p.clone())));
    }
    let dir = a.labels.parent().unwrap_or(Path::new("."));
    for d in [Some(dir), dir.parent()].into_iter().flatten() {
        let p = d.join("CATALOGUE.md");
        if p.is_file() {
            return Ok((Catalogue::read(&p)?, Some(p)));
        }
    }
    Ok((Catalogue::default(), None))
}

pub fn run(a: EvalRealArgs, models_dir: &Path) -> Result<()> {
    if a.max_range.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
        bail!("--max-range: give a distance > 0 m");
    }
    let model = Model::load(&a.model, models_dir)?;
    let scenes = read_labels(&a.labels)?;
    if scenes.is_empty() {
        bail!("{}: no scenes", a.labels.display());
    }
    let target = match (&a.class, &a.identity) {
        (Some(c), _) => Target::Class(c.clone()),
        (None, Some(id)) => Target::Identity(id.clone()),
        (None, None) => bail!("give --class or --identity"),
    };
    if let Target::Identity(id) = &target
        && !scenes
            .iter()
            .flat_map(|s| &s.objects)
            .any(|o| o.identity.as_deref() == Some(id))
    {
        bail!("{}: no object has the identity {id:?}", a.labels.display());
    }
    let (catalogue, catalogue_path) = catalogue(&a)?;
    let rule = Rule {
        target,
        catalogue,
        learned_from: a.learned_from.clone(),
    };
    let mut times = Vec::new();
    let mut rows = Vec::new();
    // Answers the shape gave and the colours refused.
    let mut refused_by_colour = 0;
    let mut grasps = GraspTally {
        gripper: match &a.gripper {
            Some(p) => crate::detect::read_gripper(p)?,
            None => Gripper::default(),
        },
        seed: a.seed,
        ..GraspTally::default()
    };
    // The planning's time per detection is what a running daemon pays: the model's surface
    // samples are taken once, not with the first scene's grasps.
    if a.grasps {
        sqscan::grasp::warm(&model);
    }
    for s in &scenes {
        let path = a.clouds.join(format!("{}.pcd", s.scene));
        let cloud = cloud::read_cloud(&path).with_context(|| format!("scene {}", s.scene))?;
        let mut params = params_for(&cloud, a.seed, None);
        params.all = true;
        params.max_range = a.max_range;
        let report = if a.ignore_colour {
            detect::detect(&cloud.points, &model, &params)
        } else {
            let (report, refused) = detect::detect_all_checked(&cloud, &model, &params);
            refused_by_colour += refused;
            report
        };
        times.push(report.timing.total_ms);
        let answers: Vec<Answer> = report
            .detections
            .iter()
            .filter(|d| d.found)
            .map(|d| Answer {
                position: d.pose.translation.vector.into(),
                // The detector's own flag for a container; otherwise the model's z axis on the
                // side of the support plane the objects are on.
                upright: d.upright.unwrap_or_else(|| {
                    report
                        .plane
                        .is_none_or(|p| (d.pose.rotation * nalgebra::Vector3::z()).dot(&p.normal) > 0.0)
                }),
            })
            .collect();
        let score = score_scene(s, &rule, &answers);
        if a.grasps {
            grasps.add(s, &score, &report, &model, &cloud, params.viewpoint)?;
        }
        rows.push((s, answers, score));
    }
    let mut summary = summarise(&rows, &rule, &times);
    if a.grasps {
        summary["grasps"] = grasps.json();
    }
    summary["catalogue"] = json!(catalogue_path.map(|p| p.display().to_string()));
    summary["refused_by_colour"] = json!(refused_by_colour);
    if a.json {
        println!("{summary}");
    } else {
        print_text(&summary, &a);
    }
    Ok(())
}

/// The grasps of the right answers, checked against the labels.
#[derive(Default)]
struct GraspTally {
    gripper: Gripper,
    /// Right answers, and those with a grasp.
    found: usize,
    with_grasp: usize,
    /// First grasps whose swept volume holds no point that is not the object's.
    clear: usize,
    /// Found objects without a grasp where a brute-force sampler over the fit, checked
    /// against the scan's points, finds one (the planner missed it), and where it finds none.
    missed: usize,
    none_exists: usize,
    /// Seeds the brute-force sampler.
    seed: u64,
    times: Vec<f64>,
    /// Where a found object got none, or the first grasp swept another's points.
    failures: Vec<Value>,
}

impl GraspTally {
    /// Plan grasps for the right answers of one scene (`report`'s found detections, in the
    /// order of the score's answers) and check the first of each against the labelled points.
    fn add(
        &mut self,
        s: &SceneLabels,
        score: &SceneScore,
        report: &detect::Report,
        model: &Model,
        cloud: &cloud::PointCloud,
        viewpoint: Option<nalgebra::Point3<f64>>,
    ) -> Result<()> {
        let found: Vec<&detect::Detection> = report.detections.iter().filter(|d| d.found).collect();
        let plane = report.plane.as_ref();
        let labels = match cloud.field("label").map(|f| &f.data) {
            Some(cloud::FieldData::U32(l)) => l,
            _ => bail!(
                "scene {}: the cloud has no u32 label field to check grasps against",
                s.scene
            ),
        };
        let gripper = self.gripper.clone();
        let wrong: std::collections::HashSet<usize> = score
            .false_answers
            .iter()
            .map(|(k, _)| *k)
            .chain(score.neutral.iter().map(|(k, _)| *k))
            .collect();
        for (k, d) in found.iter().enumerate().filter(|(k, _)| !wrong.contains(k)) {
            // The labelled object the answer is on: the nearest centroid, as the score took it.
            let p = d.pose.translation.vector;
            let Some(o) = s.objects.iter().min_by(|x, y| {
                let dx = (nalgebra::Vector3::from(x.centroid) - p).norm();
                let dy = (nalgebra::Vector3::from(y.centroid) - p).norm();
                dx.total_cmp(&dy)
            }) else {
                continue;
            };
            let Some(group) = o.group else { continue };
            let parts: Vec<Part> = d.grasp_parts(model).into_iter().map(|(p, _)| p).collect();
            let t = std::time::Instant::now();
            let planned = plan(&parts, &cloud.points, plane, viewpoint, &gripper, 1);
            self.times.push(t.elapsed().as_secs_f64() * 1e3);
            self.found += 1;
            let Some(first) = planned.first() else {
                // Whether any grasp of this gripper holds on the fit and clears the scan.
                let point = |q: &[f32; 3]| nalgebra::Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                let (own, others): (Vec<_>, Vec<_>) = cloud
                    .points
                    .iter()
                    .zip(labels)
                    .filter(|(q, _)| q.iter().all(|c| c.is_finite()))
                    .partition(|(_, l)| i64::from(**l / 10) == group);
                let own: Vec<_> = own.iter().map(|(q, _)| point(q)).collect();
                let others: Vec<_> = others.iter().map(|(q, _)| point(q)).collect();
                let scan = sqscan::eval::grasps::Truth::of_scan(parts, &others, own, plane, &gripper);
                let exists = scan.any_valid(&gripper, self.seed);
                if exists {
                    self.missed += 1;
                } else {
                    self.none_exists += 1;
                }
                let why = if exists {
                    "no grasp (a brute-force sampler finds one)"
                } else {
                    "no grasp (nor does a brute-force sampler find one)"
                };
                self.failures
                    .push(json!({"scene": s.scene, "what": o.what, "answer": k, "why": why}));
                continue;
            };
            self.with_grasp += 1;
            let swept = Swept::new(&gripper, first.opening);
            let mut inside: BTreeMap<u32, usize> = BTreeMap::new();
            for (q, &l) in cloud.points.iter().zip(labels) {
                let q = nalgebra::Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                if q.coords.iter().all(|c| c.is_finite())
                    && i64::from(l / 10) != group
                    && swept.holds(&first.pose, &q, 0.0)
                {
                    *inside.entry(l).or_default() += 1;
                }
            }
            if inside.is_empty() {
                self.clear += 1;
            } else {
                self.failures.push(json!({"scene": s.scene, "what": o.what, "answer": k,
                    "why": "the first grasp sweeps other points", "points_by_label": inside}));
            }
        }
        Ok(())
    }

    fn json(&self) -> Value {
        let (median, p95) = median_p95(&self.times);
        json!({"found": self.found, "with_grasp": self.with_grasp, "first_clear": self.clear,
            "without_where_one_exists": self.missed, "without_none_exists": self.none_exists,
            "time_ms": {"median": median, "p95": p95}, "failures": self.failures})
    }
}

fn reason(f: &FalseAnswer, objects: &[LabelledObject]) -> String {
    let what = |i: usize| {
        let o = &objects[i];
        let name = o.identity.clone().unwrap_or_else(|| o.class.clone());
        if o.what.is_empty() {
            name
        } else {
            format!("{} ({name})", o.what)
        }
    };
    match f {
        FalseAnswer::Nothing => "on nothing labelled".into(),
        FalseAnswer::OtherObject(i) => format!("on {}", what(*i)),
        FalseAnswer::Second(i) => format!("a second answer on {}", what(*i)),
        FalseAnswer::WrongUpright(i) => format!("upright flag wrong on {}", what(*i)),
    }
}

type Row<'a> = (&'a SceneLabels, Vec<Answer>, SceneScore);

/// (found, of) counts under a key.
#[derive(Default)]
struct Tally(BTreeMap<String, (usize, usize)>);

impl Tally {
    fn add(&mut self, key: &str, found: bool) {
        let c = self.0.entry(key.to_string()).or_default();
        c.0 += usize::from(found);
        c.1 += 1;
    }

    fn json(&self) -> Value {
        Value::Object(self.0.iter().map(|(k, &c)| (k.clone(), rate(c))).collect())
    }
}

fn rate(c: (usize, usize)) -> Value {
    json!({"found": c.0, "of": c.1})
}

fn summarise(rows: &[Row], rule: &Rule, times: &[f64]) -> Value {
    let mut all = Tally::default();
    let mut by_upright = Tally::default();
    let mut by_visibility = Tally::default();
    let mut by_pose = Tally::default();
    let mut by_support = Tally::default();
    let mut misses = Vec::new();
    let mut false_answers = Vec::new();
    let mut scenes_with_false = 0;
    let mut neutral = 0;
    for (s, answers, score) in rows {
        for &(i, found) in &score.targets {
            let o = &s.objects[i];
            all.add("all", found);
            by_upright.add(if o.is_upright() { "upright" } else { "upside_down" }, found);
            by_visibility.add(o.visible.as_deref().unwrap_or("unknown"), found);
            by_pose.add(&o.pose_name(), found);
            by_support.add(if o.is_stacked() { "stacked" } else { "table" }, found);
            if !found {
                misses.push(json!({"scene": s.scene, "what": o.what, "identity": o.identity,
                    "pose": o.pose_name(), "support": o.support, "visible": o.visible,
                    "upright": o.is_upright(), "centroid": o.centroid}));
            }
        }
        scenes_with_false += usize::from(!score.false_answers.is_empty());
        neutral += score.neutral.len();
        for (k, f) in &score.false_answers {
            let p = answers[*k].position;
            false_answers.push(json!({"scene": s.scene, "why": reason(f, &s.objects),
                "position": [p.x, p.y, p.z], "upright": answers[*k].upright}));
        }
    }
    let count = |t: &Tally, k: &str| rate(t.0.get(k).copied().unwrap_or_default());
    let (median, p95) = median_p95(times);
    let (kind, asked) = match &rule.target {
        Target::Class(c) => ("class", c),
        Target::Identity(id) => ("identity", id),
    };
    json!({
        kind: asked,
        "scenes": rows.len(),
        "learned_from": rule.learned_from.as_ref().map(|(s, g)| format!("{s}:{g}")),
        "recall": {
            "all": count(&all, "all"),
            "upright": count(&by_upright, "upright"),
            "upside_down": count(&by_upright, "upside_down"),
            "by_visibility": by_visibility.json(),
            "by_pose": by_pose.json(),
            "by_support": by_support.json(),
        },
        "false_answers": false_answers.len(),
        "scenes_with_false_answers": scenes_with_false,
        "neutral_answers": neutral,
        "time_ms": {"median": median, "p95": p95},
        "misses": misses,
        "false": false_answers,
    })
}

fn print_text(s: &Value, a: &EvalRealArgs) {
    let r = |v: &Value| format!("{} of {}", v["found"], v["of"]);
    let breakdown = |v: &Value| -> String {
        v.as_object()
            .map(|m| {
                m.iter()
                    .map(|(k, v)| format!("{k} {}", r(v)))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default()
    };
    let asked = match (&a.class, &a.identity) {
        (Some(c), _) => format!("class {c}"),
        (None, Some(id)) => format!("identity {id}"),
        (None, None) => String::new(),
    };
    println!(
        "{} as {asked} over {} scenes of {}",
        a.model,
        s["scenes"],
        a.labels.display()
    );
    match s["catalogue"].as_str() {
        Some(c) => println!("match radius: max(5 cm, half the size in {c})"),
        None => println!("match radius: 5 cm (no catalogue of sizes)"),
    }
    println!(
        "found: {} (upright {}, upside-down {})",
        r(&s["recall"]["all"]),
        r(&s["recall"]["upright"]),
        r(&s["recall"]["upside_down"])
    );
    println!("by pose: {}", breakdown(&s["recall"]["by_pose"]));
    println!("by support: {}", breakdown(&s["recall"]["by_support"]));
    println!("by visibility: {}", breakdown(&s["recall"]["by_visibility"]));
    println!(
        "false answers: {} in {} scenes ({} neutral answers; {} more the shape gave, refused by their colours)",
        s["false_answers"], s["scenes_with_false_answers"], s["neutral_answers"], s["refused_by_colour"]
    );
    println!(
        "time per query: median {:.1} ms, p95 {:.1} ms",
        s["time_ms"]["median"].as_f64().unwrap_or(f64::NAN),
        s["time_ms"]["p95"].as_f64().unwrap_or(f64::NAN)
    );
    for m in s["misses"].as_array().into_iter().flatten() {
        println!(
            "missed: {} {} ({}, {}, on {})",
            m["scene"].as_str().unwrap_or(""),
            m["what"].as_str().unwrap_or(""),
            m["pose"].as_str().unwrap_or("?"),
            m["visible"].as_str().unwrap_or("?"),
            m["support"].as_str().unwrap_or("the table"),
        );
    }
    for f in s["false"].as_array().into_iter().flatten() {
        println!(
            "false: {} {}",
            f["scene"].as_str().unwrap_or(""),
            f["why"].as_str().unwrap_or("")
        );
    }
    let g = &s["grasps"];
    if g.is_object() {
        println!(
            "grasps: {} of {} found objects got one; {} first grasps swept no other point; of those without, {} have one a brute-force sampler finds; {:.2} ms median",
            g["with_grasp"],
            g["found"],
            g["first_clear"],
            g["without_where_one_exists"],
            g["time_ms"]["median"].as_f64().unwrap_or(f64::NAN)
        );
        for f in g["failures"].as_array().into_iter().flatten() {
            println!(
                "grasp: {} {}: {} {}",
                f["scene"].as_str().unwrap_or(""),
                f["what"].as_str().unwrap_or(""),
                f["why"].as_str().unwrap_or(""),
                f.get("points_by_label").map(|v| v.to_string()).unwrap_or_default()
            );
        }
    }
}
