//! `sqscan eval-real` end to end on a labelled set the simulator writes: the paper's table scene,
//! labelled from the simulator's truth, twice: once as it stands, once with the cup labelled
//! upside-down (so the cup found standing is a false answer there, and a miss).

use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;

fn sqscan(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sqscan")).args(args).output().unwrap()
}

/// `sqscan eval-real` of the shipped model `model` over `labels` and the clouds in `clouds`, with
/// `args` (what is asked for and how).
fn eval_real_with(labels: &Path, clouds: &Path, model: &str, args: &[&str]) -> std::process::Output {
    let model = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("models/{model}.toml"));
    let mut all = vec![
        "eval-real",
        "--labels",
        labels.to_str().unwrap(),
        "--clouds",
        clouds.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    sqscan(&all)
}

/// `sqscan eval-real` of the shipped model `model` as `class`, with `--json` when `json`.
fn eval_real(labels: &Path, clouds: &Path, model: &str, class: &str, json: bool) -> std::process::Output {
    let json = if json { &["--json"][..] } else { &[] };
    eval_real_with(labels, clouds, model, &[&["--class", class][..], json].concat())
}

/// A labels file in the temporary directory holding the entries of `dir/labels.json` for the
/// `scenes` chosen (each must be there), named after `test`.
fn labels_of(dir: &Path, scenes: &[&str], test: &str) -> PathBuf {
    let labels: Value = serde_json::from_slice(&std::fs::read(dir.join("labels.json")).unwrap()).unwrap();
    let subset: Vec<&Value> = labels
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| scenes.contains(&s["scene"].as_str().unwrap()))
        .collect();
    assert_eq!(subset.len(), scenes.len(), "{scenes:?} in {}", dir.display());
    let file = std::env::temp_dir().join(format!("sqscan-{test}-{}.json", std::process::id()));
    std::fs::write(&file, serde_json::to_vec(&subset).unwrap()).unwrap();
    file
}

#[test]
fn eval_real_scores_a_labelled_simulated_set() {
    let dir = std::env::temp_dir().join(format!("sqscan-eval-real-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sim = dir.join("sim");
    let out = sqscan(&[
        "simulate",
        "--models-dir",
        root.join("models").to_str().unwrap(),
        root.join("scenes/fig3_table.toml").to_str().unwrap(),
        "--seed",
        "1",
        "--out",
        sim.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let said: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(said["profiles"], 150, "{said}");
    assert!(
        said["files"]
            .as_array()
            .unwrap()
            .iter()
            .all(|f| Path::new(f.as_str().unwrap()).is_file()),
        "{said}"
    );
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
    let out = eval_real(&dir.join("labels.json"), &dir, "cup", "cup", true);
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
    let out = eval_real(&dir.join("labels.json"), &dir, "cup", "cup", false);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("scene flipped") && e.contains("flipped.pcd"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `eval-real` on a few real mOSD scenes of the shared development set (skipped where it is
/// absent): learn38's two mugs standing on their rims, learn44's upright mug with its handle
/// hidden, learn8's tea box and learn30's lying can, which once were taken for mugs. Every mug is
/// found, the upside-down ones flagged so, and nothing else is answered.
#[test]
fn eval_real_on_mosd_scenes() {
    let Some(dir) = crate::common::shared_data("data/mosd_learn", "eval_real_on_mosd_scenes") else {
        return;
    };
    let file = labels_of(&dir, &["learn8", "learn30", "learn38", "learn44"], "eval-real-mosd");
    let out = eval_real(&file, &dir, "mug", "mug", true);
    let _ = std::fs::remove_file(&file);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["scenes"], 4);
    assert_eq!(summary["recall"]["all"], json!({"found": 3, "of": 3}), "{summary}");
    assert_eq!(
        summary["recall"]["upside_down"],
        json!({"found": 2, "of": 2}),
        "{summary}"
    );
    assert_eq!(summary["false_answers"], 0, "{summary}");
}

/// `sqscan eval-real` of the shipped model `model` asking for `--identity identity` on seed 1
/// (with `extra` arguments), as JSON.
fn eval_identity(labels: &Path, clouds: &Path, model: &str, identity: &str, extra: &[&str]) -> Value {
    let args = [&["--identity", identity, "--seed", "1", "--json"][..], extra].concat();
    let out = eval_real_with(labels, clouds, model, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// eval-real by identity on a labelled set the simulator writes: the two stacked scenes, each
/// object labelled with its identity, pose and support as the mOSD labels are (the free parts,
/// the pot, the tin and the larger box, by where the scene puts them). The white bowl is found
/// upside down under the can and standing on the pot, the can standing on the bowl and lying
/// across the tin, the mug on the book, the learned box and not the larger one beside it; recall
/// is broken down by pose and by support, and nothing else is answered.
#[test]
fn eval_real_by_identity_on_stacked_simulated_scenes() {
    let dir = std::env::temp_dir().join(format!("sqscan-eval-identity-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // (scene, [(object, class, pose, support)], [(part, centroid, pose)])
    type Objects<'a> = &'a [(&'a str, &'a str, &'a str, &'a str)];
    type Parts<'a> = &'a [(&'a str, [f64; 3], &'a str)];
    let scenes: [(&str, Objects, Parts); 2] = [
        (
            "mug_on_book",
            &[
                ("book", "other", "flat", "table"),
                ("mug", "mug", "standing", "book"),
                ("bowl", "white_bowl", "upside_down", "table"),
                ("can", "other", "standing", "white_bowl"),
            ],
            &[],
        ),
        (
            "bowl_on_pot",
            &[
                ("bowl", "white_bowl", "standing", "pot"),
                ("can", "other", "lying", "tin"),
                ("box", "other", "flat", "table"),
            ],
            &[
                ("pot", [0.80, 0.18, 0.77], "upside_down"),
                ("tin", [0.95, -0.12, 0.76], "flat"),
                ("big_box", [0.70, -0.31, 0.752], "flat"),
            ],
        ),
    ];
    let mut labels = Vec::new();
    for (name, objects, parts) in scenes {
        let sim = dir.join(name);
        let out = sqscan(&[
            "simulate",
            "--models-dir",
            root.join("models").to_str().unwrap(),
            root.join(format!("scenes/stacked/{name}.toml")).to_str().unwrap(),
            "--seed",
            "1",
            "--out",
            sim.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        std::fs::copy(sim.join("cloud.pcd"), dir.join(format!("{name}.pcd"))).unwrap();
        let truth: Value = serde_json::from_slice(&std::fs::read(sim.join("truth.json")).unwrap()).unwrap();
        let mut labelled = Vec::new();
        for (object, class, pose, support) in objects {
            let t = truth["objects"]
                .as_array()
                .unwrap()
                .iter()
                .find(|o| o["name"] == *object)
                .unwrap();
            // The identity is the model's: the white bowl and the can are one physical object
            // each, in both scenes.
            let mut o = json!({"class": class, "identity": t["model"], "what": object, "pose": pose,
                "support": support, "centroid": t["pose"]["position"], "visible": "full", "size": 0.2});
            if matches!(*class, "mug" | "white_bowl") {
                o["upright"] = json!(*pose != "upside_down");
            }
            if *object == "box" {
                o["group"] = json!(4);
            }
            labelled.push(o);
        }
        for (part, centroid, pose) in parts {
            labelled.push(
                json!({"class": "other", "identity": part, "pose": pose, "support": "table",
                "centroid": centroid, "visible": "full", "size": 0.2}),
            );
        }
        labels.push(json!({"scene": name, "objects": labelled}));
    }
    let file = dir.join("labels.json");
    std::fs::write(&file, serde_json::to_vec(&labels).unwrap()).unwrap();

    let r = eval_identity(&file, &dir, "white_bowl", "white_bowl", &[]);
    assert_eq!(r["recall"]["all"], json!({"found": 2, "of": 2}), "{r}");
    assert_eq!(
        r["recall"]["by_pose"],
        json!({"standing": {"found": 1, "of": 1}, "upside_down": {"found": 1, "of": 1}}),
        "{r}"
    );
    assert_eq!(
        r["recall"]["by_support"],
        json!({"stacked": {"found": 1, "of": 1}, "table": {"found": 1, "of": 1}}),
        "{r}"
    );
    assert_eq!(r["false_answers"], 0, "{r}");

    let r = eval_identity(&file, &dir, "learned_cylinder", "learned_cylinder", &[]);
    assert_eq!(r["recall"]["all"], json!({"found": 2, "of": 2}), "{r}");
    assert_eq!(r["recall"]["by_pose"]["lying"], json!({"found": 1, "of": 1}), "{r}");
    assert_eq!(
        r["recall"]["by_support"]["stacked"],
        json!({"found": 2, "of": 2}),
        "{r}"
    );
    assert_eq!(r["false_answers"], 0, "{r}");

    let r = eval_identity(&file, &dir, "mug", "mug", &[]);
    assert_eq!(
        r["recall"]["by_support"],
        json!({"stacked": {"found": 1, "of": 1}}),
        "{r}"
    );
    assert_eq!(r["false_answers"], 0, "{r}");

    let r = eval_identity(&file, &dir, "learned_box", "learned_box", &[]);
    assert_eq!(r["recall"]["all"], json!({"found": 1, "of": 1}), "{r}");
    assert_eq!(r["false_answers"], 0, "{r}");

    // With grasps: the box (the only object with a label group to check the sweep against)
    // gets one, and its gripper sweeps none of the other labelled points.
    let r = eval_identity(&file, &dir, "learned_box", "learned_box", &["--grasps"]);
    let g = &r["grasps"];
    assert_eq!(
        (&g["found"], &g["with_grasp"], &g["first_clear"]),
        (&json!(1), &json!(1), &json!(1)),
        "{r}"
    );
    assert!(g["time_ms"]["median"].as_f64().is_some_and(|t| t > 0.0), "{r}");
    // With a gripper opening 20 mm it gets none, and no grasp a brute-force sampler tries
    // holds on its fit and clears the scan either.
    let narrow = dir.join("narrow_gripper.toml");
    std::fs::write(&narrow, "max_opening = 0.02\nmin_opening = 0.0\n").unwrap();
    let narrow = narrow.display().to_string();
    let r = eval_identity(
        &file,
        &dir,
        "learned_box",
        "learned_box",
        &["--grasps", "--gripper", &narrow],
    );
    let g = &r["grasps"];
    assert_eq!(
        (
            &g["found"],
            &g["with_grasp"],
            &g["without_none_exists"],
            &g["without_where_one_exists"]
        ),
        (&json!(1), &json!(0), &json!(1), &json!(0)),
        "{r}"
    );

    // Learned from the box's view in the second scene (its group 4): that answer is neutral,
    // and nothing is left to find.
    let r = eval_identity(
        &file,
        &dir,
        "learned_box",
        "learned_box",
        &["--learned-from", "bowl_on_pot:4"],
    );
    assert_eq!(r["recall"]["all"], json!({"found": 0, "of": 0}), "{r}");
    assert_eq!(
        (&r["neutral_answers"], &r["false_answers"]),
        (&json!(1), &json!(0)),
        "{r}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// eval-real by identity on the stacked mOSD scenes of the shared development set (skipped where
/// it is absent): the white bowl upside down under the tower of test42 and on the biscuit tin of
/// test56, standing on a book in test58 and on the upturned yellow pot in test60, and the mug on
/// the biscuit tin of test32, all found, with no false answer, by CATALOGUE.md's rule.
#[test]
fn eval_real_by_identity_on_stacked_mosd_scenes() {
    let Some(dir) = crate::common::shared_data("data/mosd_test_even", "eval_real_by_identity_on_stacked_mosd_scenes")
    else {
        return;
    };
    let catalogue = dir.join("../CATALOGUE.md");
    let file = labels_of(
        &dir,
        &["test32", "test42", "test56", "test58", "test60"],
        "eval-stacked-mosd",
    );
    let cat = ["--catalogue", catalogue.to_str().unwrap()];
    let bowl = eval_identity(&file, &dir, "white_bowl", "white_bowl", &cat);
    let mug = eval_identity(&file, &dir, "mug", "mug_printed", &cat);
    let _ = std::fs::remove_file(&file);
    assert_eq!(bowl["recall"]["all"], json!({"found": 4, "of": 4}), "{bowl}");
    assert_eq!(
        bowl["recall"]["by_support"]["stacked"],
        json!({"found": 3, "of": 3}),
        "{bowl}"
    );
    assert_eq!(bowl["recall"]["upside_down"], json!({"found": 2, "of": 2}), "{bowl}");
    assert_eq!(bowl["false_answers"], 0, "{bowl}");
    assert_eq!(mug["recall"]["all"], json!({"found": 1, "of": 1}), "{mug}");
    assert_eq!(mug["false_answers"], 0, "{mug}");
}

/// The plain mug of mOSD learn39 (skipped without the shared set), a few millimetres taller than
/// the `mug` model: on seed 4 its fit, axis held on the table's normal, settled 16 mm above the
/// table with its top above the rim, and the mug was missed. Fitted again from where it would
/// rest on the table, it is found (both mugs of the scene, on seeds 1-8).
#[test]
fn the_floating_mug_of_learn39_rests_on_the_table() {
    let Some(dir) = crate::common::shared_data("data/mosd_learn", "the_floating_mug_of_learn39_rests_on_the_table")
    else {
        return;
    };
    let file = labels_of(&dir, &["learn39"], "eval-learn39");
    for seed in 1..=8 {
        let seed_arg = seed.to_string();
        let out = eval_real_with(&file, &dir, "mug", &["--class", "mug", "--seed", &seed_arg, "--json"]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let r: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(r["recall"]["all"], json!({"found": 2, "of": 2}), "seed {seed}: {r}");
        assert_eq!(r["false_answers"], 0, "seed {seed}: {r}");
    }
    let _ = std::fs::remove_file(&file);
}
