//! `sqscan eval-real` end to end on a labelled set the simulator writes: the paper's table scene,
//! labelled from the simulator's truth, twice: once as it stands, once with the cup labelled
//! upside-down (so the cup found standing is a false answer there, and a miss).

use serde_json::{Value, json};
use std::path::PathBuf;
use std::process::Command;

fn sqscan(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sqscan")).args(args).output().unwrap()
}

#[test]
fn eval_real_scores_a_labelled_simulated_set() {
    let dir = std::env::temp_dir().join(format!("sqscan-eval-real-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sim = dir.join("sim");
    let out = sqscan(&[
        "--models-dir",
        root.join("models").to_str().unwrap(),
        "simulate",
        root.join("scenes/fig3_table.toml").to_str().unwrap(),
        "--seed",
        "1",
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let truth: Value = serde_json::from_slice(&std::fs::read(sim.join("truth.json")).unwrap()).unwrap();
    let objects = |cup_upright: bool| -> Vec<Value> {
        truth["objects"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| {
                let cup = o["name"] == "cup";
                json!({
                    "class": if cup { "cup" } else { "other" },
                    "what": o["name"],
                    "centroid": o["pose"]["position"],
                    "visible": "full",
                    "upright": !cup || cup_upright,
                })
            })
            .collect()
    };
    let labels = json!([
        {"scene": "standing", "objects": objects(true)},
        {"scene": "flipped", "objects": objects(false)},
    ]);
    std::fs::write(dir.join("labels.json"), labels.to_string()).unwrap();
    for scene in ["standing", "flipped"] {
        std::fs::copy(sim.join("cloud.pcd"), dir.join(format!("{scene}.pcd"))).unwrap();
    }
    let out = sqscan(&[
        "--models-dir",
        root.join("models").to_str().unwrap(),
        "eval-real",
        "--labels",
        dir.join("labels.json").to_str().unwrap(),
        "--clouds",
        dir.to_str().unwrap(),
        "--model",
        "cup",
        "--class",
        "cup",
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["scenes"], 2);
    assert_eq!(r["recall"]["all"], json!({"found": 1, "of": 2}), "{r}");
    assert_eq!(r["recall"]["upright"], json!({"found": 1, "of": 1}), "{r}");
    assert_eq!(r["recall"]["upside_down"], json!({"found": 0, "of": 1}), "{r}");
    assert_eq!(r["false_answers"], 1, "{r}");
    assert_eq!(r["false"][0]["scene"], "flipped");
    assert!(
        r["false"][0]["why"].as_str().unwrap().starts_with("upright flag wrong"),
        "{r}"
    );
    assert!(r["time_ms"]["median"].as_f64().unwrap() > 0.0);

    // A scene without its cloud is named.
    std::fs::remove_file(dir.join("flipped.pcd")).unwrap();
    let out = sqscan(&[
        "eval-real",
        "--labels",
        dir.join("labels.json").to_str().unwrap(),
        "--clouds",
        dir.to_str().unwrap(),
        "--model",
        root.join("models/cup.toml").to_str().unwrap(),
        "--class",
        "cup",
    ]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("scene flipped") && e.contains("flipped.pcd"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
