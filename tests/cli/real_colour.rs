//! Colour on real scans nobody here made (`tests/data/real`, see its SOURCES.md): a model
//! learned from a coloured cloud keeps its object's colours, and what the geometry takes for the
//! object but shows other colours is not it.

use crate::common::real_data as data;
use sqscan::cloud::{FieldData, read_cloud};
use std::path::{Path, PathBuf};

fn sqscan(args: &[&std::ffi::OsStr]) -> serde_json::Value {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Every detection of `model` in the carried `scene` (`--all`, seed 5), with `extra` flags:
/// each one's position and colour similarity.
fn found_in(model: &Path, scene: &str, extra: &[&str]) -> Vec<([f64; 3], Option<f64>)> {
    let models = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut args: Vec<&std::ffi::OsStr> = vec!["detect".as_ref(), "--model".as_ref(), model.as_ref()];
    let cloud = data(scene);
    args.extend([
        "--cloud".as_ref(),
        cloud.as_os_str(),
        "--seed".as_ref(),
        "5".as_ref(),
        "--all".as_ref(),
    ]);
    args.extend(["--models-dir".as_ref(), models.as_os_str()]);
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    let report = sqscan(&args);
    report["detections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            let p = &d["pose"]["position"];
            (
                [0, 1, 2].map(|k| p[k].as_f64().unwrap()),
                d.get("colour").and_then(|c| c.as_f64()),
            )
        })
        .collect()
}

/// The mean of the points labelled object `group` (label / 10).
fn labelled_centre(scene: &str, group: u32) -> [f64; 3] {
    let cloud = read_cloud(&data(scene)).unwrap();
    let Some(FieldData::U32(labels)) = cloud.field("label").map(|f| &f.data) else {
        panic!("{scene}: no label field");
    };
    let (mut sum, mut n) = ([0.0; 3], 0.0);
    for (p, &l) in cloud.points.iter().zip(labels) {
        if l >= 20 && l / 10 == group && p.iter().all(|v| v.is_finite()) {
            for k in 0..3 {
                sum[k] += f64::from(p[k]);
            }
            n += 1.0;
        }
    }
    sum.map(|s| s / n)
}

/// The white floral canister, learned from mOSD learn40, is 83 mm across and 104 mm tall: the
/// geometry alone takes for it the end of the orange Pringles can lying in learn30 (as thick,
/// its other end hidden behind the grey block), which shares almost none of its colours. With
/// them it is found nowhere in learn30, and still found where it stands in test44; eval-real
/// counts the answer the colours refused.
#[test]
fn the_floral_canister_is_not_found_on_the_lying_pringles_can() {
    let dir = std::env::temp_dir().join(format!("sqscan-colour-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("floral_canister.toml");
    let cloud = data("learn40.pcd");
    let learned = sqscan(&[
        "learn".as_ref(),
        "--cloud".as_ref(),
        cloud.as_os_str(),
        "--label".as_ref(),
        "3".as_ref(),
        "--name".as_ref(),
        "floral_canister".as_ref(),
        "--force".as_ref(),
        "--out".as_ref(),
        model.as_os_str(),
    ]);
    assert_eq!(learned["colour"], true, "{learned}");
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(text.contains("\ncolour = ["), "{text}");

    assert_eq!(found_in(&model, "learn30.pcd", &[]), vec![]);
    let by_shape = found_in(&model, "learn30.pcd", &["--ignore-colour"]);
    assert_eq!(
        by_shape.len(),
        1,
        "the geometry alone finds it on the can: {by_shape:?}"
    );

    let found = found_in(&model, "test44.pcd", &[]);
    let truth = labelled_centre("test44.pcd", 6);
    let near: Vec<_> = found
        .iter()
        .filter(|(p, _)| (0..3).map(|k| (p[k] - truth[k]).powi(2)).sum::<f64>().sqrt() < 0.05)
        .collect();
    assert_eq!(near.len(), 1, "{found:?} against the labelled {truth:?}");
    assert!(near[0].1.is_some_and(|c| c > 0.6), "{near:?}");

    // Asked for one answer: in learn30 the shape's best is refused by its colours and nothing
    // else passes ("not here", with the share it had); in test44 the canister.
    let one = |scene: &str| {
        let models = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models");
        let cloud = data(scene);
        let args: [&std::ffi::OsStr; 9] = [
            "detect".as_ref(),
            "--model".as_ref(),
            model.as_os_str(),
            "--cloud".as_ref(),
            cloud.as_os_str(),
            "--seed".as_ref(),
            "5".as_ref(),
            "--models-dir".as_ref(),
            models.as_os_str(),
        ];
        sqscan(&args)
    };
    let refused = one("learn30.pcd");
    assert_eq!(refused["found"], false, "{refused}");
    assert!(refused["colour"].as_f64().is_some_and(|c| c < 0.35), "{refused}");
    let single = one("test44.pcd");
    assert_eq!(single["found"], true, "{single}");

    // eval-real counts what the colours refused: learn30's can is no false answer, but one
    // refused; test44's canister is found either way.
    let labels = dir.join("labels.json");
    let object = |scene: &str, group: u32, identity: &str| {
        serde_json::json!({"class": "other", "identity": identity, "group": group,
            "centroid": labelled_centre(scene, group), "visible": "full"})
    };
    let scenes = serde_json::json!([
        {"scene": "learn30", "objects": [object("learn30.pcd", 2, "grey_block"), object("learn30.pcd", 3, "pringles_can")]},
        {"scene": "test44", "objects": [object("test44.pcd", 6, "floral_canister")]},
    ]);
    std::fs::write(&labels, scenes.to_string()).unwrap();
    let clouds = data("learn30.pcd").parent().unwrap().to_owned();
    let eval = |extra: &[&str]| {
        let mut args: Vec<&std::ffi::OsStr> = vec!["eval-real".as_ref(), "--labels".as_ref(), labels.as_os_str()];
        args.extend([
            "--clouds".as_ref(),
            clouds.as_os_str(),
            "--model".as_ref(),
            model.as_os_str(),
        ]);
        args.extend(["--identity", "floral_canister", "--seed", "5", "--json"].map(std::ffi::OsStr::new));
        args.extend(extra.iter().map(std::ffi::OsStr::new));
        sqscan(&args)
    };
    let checked = eval(&[]);
    assert_eq!(checked["recall"]["all"]["found"], 1, "{checked}");
    assert_eq!(
        (checked["false_answers"].as_u64(), checked["refused_by_colour"].as_u64()),
        (Some(0), Some(1)),
        "{checked}"
    );
    let by_shape = eval(&["--ignore-colour"]);
    assert_eq!(by_shape["recall"]["all"]["found"], 1, "{by_shape}");
    assert_eq!(
        (
            by_shape["false_answers"].as_u64(),
            by_shape["refused_by_colour"].as_u64()
        ),
        (Some(1), Some(0)),
        "{by_shape}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
