//! `sqscan eval-real`: the detector on real scans labelled by object class: recall, false
//! answers and time per query, with the misses and false answers by scene.

use crate::detect::params_for;
use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::{Value, json};
use sqscan::cloud;
use sqscan::detect;
use sqscan::eval::median_p95;
use sqscan::eval::real::{Answer, FalseAnswer, SceneScore, read_labels, score_scene};
use sqscan::model::Model;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct EvalRealArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Labels file (JSON: one entry a scene, its objects with class, centroid, visible, upright)
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
    class: String,
    /// Seed of every random choice of the search
    #[arg(long, default_value_t = 5)]
    seed: u64,
    /// Ignore points farther than this from the viewpoint (m)
    #[arg(long, value_name = "M")]
    max_range: Option<f64>,
    /// Print one JSON object instead of the text report
    #[arg(long)]
    json: bool,
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
    let mut times = Vec::new();
    let mut rows = Vec::new();
    for s in &scenes {
        let path = a.clouds.join(format!("{}.pcd", s.scene));
        let cloud = cloud::read_cloud(&path).with_context(|| format!("scene {}", s.scene))?;
        let mut params = params_for(&cloud, a.seed, None);
        params.all = true;
        params.max_range = a.max_range;
        let report = detect::detect(&cloud.points, &model, &params);
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
        let score = score_scene(&s.objects, &a.class, &answers);
        rows.push((s, answers, score));
    }
    let summary = summarise(&rows, &a.class, &times);
    if a.json {
        println!("{summary}");
    } else {
        print_text(&summary, &a);
    }
    Ok(())
}

fn reason(f: &FalseAnswer, objects: &[sqscan::eval::real::LabelledObject]) -> String {
    let what = |i: usize| {
        let o = &objects[i];
        if o.what.is_empty() {
            o.class.clone()
        } else {
            format!("{} ({})", o.what, o.class)
        }
    };
    match f {
        FalseAnswer::Nothing => "on nothing labelled".into(),
        FalseAnswer::OtherObject(i) => format!("on {}", what(*i)),
        FalseAnswer::Second(i) => format!("a second answer on {}", what(*i)),
        FalseAnswer::WrongUpright(i) => format!("upright flag wrong on {}", what(*i)),
    }
}

type Row<'a> = (&'a sqscan::eval::real::SceneLabels, Vec<Answer>, SceneScore);

fn summarise(rows: &[Row], class: &str, times: &[f64]) -> Value {
    // (found, total) overall, upright, upside-down, and by visibility.
    let mut all = (0, 0);
    let mut upright = (0, 0);
    let mut upside_down = (0, 0);
    let mut by_visibility: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut misses = Vec::new();
    let mut false_answers = Vec::new();
    let mut scenes_with_false = 0;
    for (s, answers, score) in rows {
        for &(i, found) in &score.targets {
            let o = &s.objects[i];
            let add = |c: &mut (usize, usize)| {
                c.0 += usize::from(found);
                c.1 += 1;
            };
            add(&mut all);
            add(if o.is_upright() { &mut upright } else { &mut upside_down });
            add(by_visibility
                .entry(o.visible.clone().unwrap_or_else(|| "unknown".into()))
                .or_default());
            if !found {
                misses.push(
                    json!({"scene": s.scene, "what": o.what, "visible": o.visible, "upright": o.is_upright(),
                    "centroid": o.centroid}),
                );
            }
        }
        scenes_with_false += usize::from(!score.false_answers.is_empty());
        for (k, f) in &score.false_answers {
            let p = answers[*k].position;
            false_answers.push(json!({"scene": s.scene, "why": reason(f, &s.objects),
                "position": [p.x, p.y, p.z], "upright": answers[*k].upright}));
        }
    }
    let rate = |c: (usize, usize)| json!({"found": c.0, "of": c.1});
    let (median, p95) = median_p95(times);
    json!({
        "class": class,
        "scenes": rows.len(),
        "recall": {
            "all": rate(all),
            "upright": rate(upright),
            "upside_down": rate(upside_down),
            "by_visibility": by_visibility.into_iter().map(|(k, v)| (k, rate(v))).collect::<serde_json::Map<_, _>>(),
        },
        "false_answers": false_answers.len(),
        "scenes_with_false_answers": scenes_with_false,
        "time_ms": {"median": median, "p95": p95},
        "misses": misses,
        "false": false_answers,
    })
}

fn print_text(s: &Value, a: &EvalRealArgs) {
    let r = |v: &Value| format!("{} of {}", v["found"], v["of"]);
    println!(
        "{} as {} over {} scenes of {}",
        a.model,
        a.class,
        s["scenes"],
        a.labels.display()
    );
    println!(
        "found: {} (upright {}, upside-down {})",
        r(&s["recall"]["all"]),
        r(&s["recall"]["upright"]),
        r(&s["recall"]["upside_down"])
    );
    if let Some(m) = s["recall"]["by_visibility"].as_object() {
        let parts: Vec<String> = m.iter().map(|(k, v)| format!("{k} {}", r(v))).collect();
        println!("by visibility: {}", parts.join(", "));
    }
    println!(
        "false answers: {} in {} scenes",
        s["false_answers"], s["scenes_with_false_answers"]
    );
    println!(
        "time per query: median {:.1} ms, p95 {:.1} ms",
        s["time_ms"]["median"].as_f64().unwrap_or(f64::NAN),
        s["time_ms"]["p95"].as_f64().unwrap_or(f64::NAN)
    );
    for m in s["misses"].as_array().into_iter().flatten() {
        println!(
            "missed: {} {} ({}{})",
            m["scene"].as_str().unwrap_or(""),
            m["what"].as_str().unwrap_or(""),
            m["visible"].as_str().unwrap_or("?"),
            if m["upright"] == json!(false) {
                ", upside-down"
            } else {
                ""
            }
        );
    }
    for f in s["false"].as_array().into_iter().flatten() {
        println!(
            "false: {} {}",
            f["scene"].as_str().unwrap_or(""),
            f["why"].as_str().unwrap_or("")
        );
    }
}
