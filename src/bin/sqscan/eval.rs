//! `sqscan eval`: detection rate, false "found" rate, time and pose errors against the
//! simulator's ground truth.

use crate::detect::parse_pose;
use anyhow::{Result, bail};
use clap::Args;
use nalgebra::Isometry3;
use serde_json::json;
use sqscan::detect::Params;
use sqscan::eval::{self, MAX_POSITION_ERROR_M, MAX_ROTATION_ERROR_RAD, Symmetry, median_p95};
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
        trials.push(eval::trial(&scene, &model, truth, &symmetry, seed, &params));
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
    if a.json {
        println!(
            "{}",
            json!({
                "scene": a.scene.display().to_string(), "model": model.name, "object": object,
                "absent": a.absent, "trials": a.trials, "correct": correct,
                "detection_rate": correct as f64 / n, "found": found, "false_found": false_found,
                "time_ms": {"median": t_med, "p95": t_p95},
                "position_error_m": {"median": if a.absent { f64::NAN } else { p_med }, "p95": if a.absent { f64::NAN } else { p_p95 }},
                "rotation_error_deg": {"median": if a.absent { f64::NAN } else { r_med }, "p95": if a.absent { f64::NAN } else { r_p95 }},
            })
        );
        return Ok(());
    }
    println!("scene      {}", a.scene.display());
    println!(
        "model      {} (scene object {:?}{})",
        model.name,
        object,
        if a.absent { ", removed" } else { "" }
    );
    println!("trials     {}", a.trials);
    if a.absent {
        println!("false found {false_found} ({:.1} %)", 100.0 * false_found as f64 / n);
    } else {
        println!(
            "correct    {correct} ({:.1} %)  [position < {} mm, rotation < {:.0} deg, found]",
            100.0 * correct as f64 / n,
            MAX_POSITION_ERROR_M * 1e3,
            MAX_ROTATION_ERROR_RAD.to_degrees()
        );
        println!("found      {found}");
        println!("position   median {:.2} mm, p95 {:.2} mm", p_med * 1e3, p_p95 * 1e3);
        println!("rotation   median {r_med:.2} deg, p95 {r_p95:.2} deg");
    }
    println!("time       median {t_med:.1} ms, p95 {t_p95:.1} ms");
    Ok(())
}
