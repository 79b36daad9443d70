//! `sqscan eval`: detection rate, false "found" rate, time and pose errors against the
//! simulator's ground truth.

use crate::detect::{parse_pose, read_gripper};
use anyhow::{Result, bail};
use clap::Args;
use nalgebra::Isometry3;
use serde_json::json;
use sqscan::detect::Params;
use sqscan::eval::{self, MAX_POSITION_ERROR_M, MAX_ROTATION_ERROR_RAD, Symmetry, grasps, median_p95};
use sqscan::grasp::Gripper;
use sqscan::model::Model;
use sqscan::sim::Scene;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct EvalArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Scene file (scenes/*.toml)
    #[arg(long)]
    scene: PathBuf,
    /// Model name or file to detect
    #[arg(long)]
    model: String,
    /// Trials: each re-simulates the sweep with new noise and searches with a new seed
    #[arg(long, default_value_t = 100)]
    trials: usize,
    /// First seed (trial k uses seed + k for both the noise and the search)
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Remove the object from the scene and count false "found" answers
    #[arg(long)]
    absent: bool,
    /// The scene object the model is (its pose is the truth) [default: the object of the same
    /// model, else the one with the model's first part's shape]; for a learned model
    #[arg(long, value_name = "NAME")]
    truth_object: Option<String>,
    /// The model's frame in the truth object's frame, "x,y,z,qx,qy,qz,qw" (m, quaternion): the
    /// truth is the object's pose composed with it. A learned model's frame is where the learner
    /// put it on the object (its `model_pose` in the learning cloud, composed with the inverse
    /// of the object's pose there), not the shipped model's [default: the identity]
    #[arg(long, value_name = "X,Y,Z,QX,QY,QZ,QW", value_parser = parse_pose, allow_hyphen_values = true)]
    model_in_object: Option<Isometry3<f64>>,
    /// RANSAC trials per hypothesis of the detector (`detect --trials`) [default: the
    /// detector's]
    #[arg(long, value_name = "N")]
    ransac_trials: Option<usize>,
    /// Print one JSON object instead of a table
    #[arg(long)]
    json: bool,
    /// Plan a grasp for every correct detection and judge it against the truth: returned where
    /// a brute-force sampler over the true object and scene finds a valid one, and the first
    /// grasp valid (contacts within 3 mm of the true surface and in the friction cone, the
    /// gripper 3 mm clear of the true table and every other true object)
    #[arg(long)]
    grasps: bool,
    /// The gripper's settings for --grasps: a TOML file of the [gripper] table's keys
    /// [default: a Robotiq 2F-85-class gripper]
    #[arg(long, value_name = "GRIPPER.toml")]
    gripper: Option<PathBuf>,
}

pub fn eval(a: EvalArgs, models_dir: &Path) -> Result<()> {
    if a.trials == 0 || a.ransac_trials == Some(0) {
        bail!("--trials and --ransac-trials must be at least 1");
    }
    let scene = Scene::from_file(&a.scene, models_dir)?;
    let model = Model::load(&a.model, models_dir)?;
    let by_name = a
        .truth_object
        .as_ref()
        .map(|n| {
            scene
                .objects
                .iter()
                .find(|o| &o.name == n)
                .map(|o| (o.name.clone(), o.pose))
                .ok_or_else(|| anyhow::anyhow!("--truth-object: the scene has no object {n:?}"))
        })
        .transpose()?;
    let Some((object, truth)) = by_name.or_else(|| eval::truth_pose(&scene, &model)) else {
        bail!(
            "{}: no object of model {:?} (or with its first part's shape) in the scene",
            a.scene.display(),
            model.name
        );
    };
    let truth = match a.model_in_object {
        Some(m) => truth * m,
        None => truth,
    };
    let scene = if a.absent { scene.without_object(&object) } else { scene };
    let symmetry = Symmetry::of(&model);
    let progress = std::io::stderr().is_terminal();
    let gripper = match &a.gripper {
        Some(p) => read_gripper(p)?,
        None => Gripper::default(),
    };
    let truth_world = (a.grasps && !a.absent).then(|| grasps::Truth::new(&scene, &object, &model, &truth));
    let mut verdicts = Vec::new();
    let mut trials = Vec::with_capacity(a.trials);
    for k in 0..a.trials {
        let seed = a.seed.wrapping_add(k as u64);
        let defaults = Params::default();
        let params = Params {
            seed,
            trials: a.ransac_trials.unwrap_or(defaults.trials),
            ..defaults
        };
        let truth = if a.absent { None } else { Some(&truth) };
        let mut t = eval::trial(&scene, &model, truth, &symmetry, seed, &params);
        let cloud = std::mem::take(&mut t.cloud);
        if let (Some(world), true, Some(d)) = (&truth_world, t.correct, t.report.detections.first()) {
            let scan = grasps::Scan {
                cloud: &cloud,
                plane: t.report.plane.as_ref(),
                viewpoint: t.viewpoint,
            };
            verdicts.push(grasps::judge(world, d, &model, &scan, &gripper, seed));
        }
        trials.push(t);
        if progress {
            let done = k + 1;
            let bar = "#".repeat(done * 30 / a.trials);
            eprint!("\r[{bar:<30}] {done}/{}", a.trials);
            let _ = std::io::stderr().flush();
        }
    }
    if progress {
        eprintln!();
    }
    let n = trials.len() as f64;
    let correct = trials.iter().filter(|t| t.correct).count();
    let found = trials.iter().filter(|t| t.found).count();
    let (t_med, t_p95) = median_p95(&trials.iter().map(|t| t.time_ms).collect::<Vec<_>>());
    let (p_med, p_p95) = median_p95(&trials.iter().map(|t| t.position_error).collect::<Vec<_>>());
    let (r_med, r_p95) = median_p95(&trials.iter().map(|t| t.rotation_error.to_degrees()).collect::<Vec<_>>());
    let false_found = if a.absent { found } else { 0 };
    let grasp_summary = truth_world.as_ref().map(|_| grasp_summary(&verdicts));
    let summary = json!({
        "scene": a.scene.display().to_string(), "model": model.name, "object": object,
        "absent": a.absent, "trials": a.trials, "correct": correct,
        "detection_rate": correct as f64 / n, "found": found, "false_found": false_found,
        "time_ms": {"median": t_med, "p95": t_p95},
        "position_error_m": {"median": if a.absent { f64::NAN } else { p_med }, "p95": if a.absent { f64::NAN } else { p_p95 }},
        "rotation_error_deg": {"median": if a.absent { f64::NAN } else { r_med }, "p95": if a.absent { f64::NAN } else { r_p95 }},
        "grasps": grasp_summary,
    });
    if a.json {
        println!("{summary}");
    } else {
        print_text(&summary);
    }
    Ok(())
}

/// The summary as a table for a terminal.
fn print_text(s: &serde_json::Value) {
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let n = f(&s["trials"]);
    println!("scene      {}", s["scene"].as_str().unwrap_or("?"));
    let absent = s["absent"] == true;
    println!(
        "model      {} (scene object {}{})",
        s["model"].as_str().unwrap_or("?"),
        s["object"],
        if absent { ", removed" } else { "" }
    );
    println!("trials     {}", s["trials"]);
    if absent {
        println!(
            "false found {} ({:.1} %)",
            s["false_found"],
            100.0 * f(&s["false_found"]) / n
        );
    } else {
        println!(
            "correct    {} ({:.1} %)  [position < {} mm, rotation < {:.0} deg, found]",
            s["correct"],
            100.0 * f(&s["correct"]) / n,
            MAX_POSITION_ERROR_M * 1e3,
            MAX_ROTATION_ERROR_RAD.to_degrees()
        );
        println!("found      {}", s["found"]);
        let (p, r) = (&s["position_error_m"], &s["rotation_error_deg"]);
        println!(
            "position   median {:.2} mm, p95 {:.2} mm",
            f(&p["median"]) * 1e3,
            f(&p["p95"]) * 1e3
        );
        println!(
            "rotation   median {:.2} deg, p95 {:.2} deg",
            f(&r["median"]),
            f(&r["p95"])
        );
    }
    println!(
        "time       median {:.1} ms, p95 {:.1} ms",
        f(&s["time_ms"]["median"]),
        f(&s["time_ms"]["p95"])
    );
    let g = &s["grasps"];
    if g.is_object() {
        println!(
            "grasps     {} of {} correct detections where a valid grasp exists got one; first grasp valid in {} of {}; {:.2} ms median",
            g["planned_where_one_exists"],
            g["exists"],
            g["first_valid"],
            g["planned"],
            f(&g["time_ms"]["median"])
        );
        for (why, k) in g["invalid"].as_object().into_iter().flatten() {
            println!("           first grasp invalid {k} times: {why}");
        }
    }
}

/// The grasp verdicts of the correct detections, summed.
fn grasp_summary(v: &[grasps::Verdict]) -> serde_json::Value {
    let exists = v.iter().filter(|x| x.exists).count();
    let planned_where = v.iter().filter(|x| x.exists && x.planned).count();
    let planned = v.iter().filter(|x| x.planned).count();
    let valid = v.iter().filter(|x| matches!(x.first_valid, Some(Ok(())))).count();
    let mut invalid = std::collections::BTreeMap::new();
    for x in v {
        if let Some(Err(why)) = x.first_valid {
            *invalid.entry(why).or_insert(0usize) += 1;
        }
    }
    let (median, p95) = median_p95(&v.iter().map(|x| x.time_ms).collect::<Vec<_>>());
    json!({"correct": v.len(), "exists": exists, "planned_where_one_exists": planned_where,
        "planned": planned, "first_valid": valid, "invalid": invalid,
        "time_ms": {"median": median, "p95": p95}})
}
