//! The detector on simulated sweeps of the paper's scenes: it finds what is there at the right
//! pose, says "not here" when it is not, gives the same answer for the same seed, and survives
//! degenerate input.

use crate::common::root;
use sqscan::detect::{Params, detect};
use sqscan::eval::{self, Symmetry};
use sqscan::model::Model;
use sqscan::sim::{Scene, simulate};
use std::path::Path;

fn scene(name: &str) -> Scene {
    Scene::from_file(&root().join("scenes").join(name), &root().join("models")).unwrap()
}

fn model(name: &str) -> Model {
    Model::load(name, &root().join("models")).unwrap()
}

/// Detect `model_name` in `scene_name` for a few noise and search seeds; every answer must be
/// found and within the evaluation's tolerance of the truth (10 mm, 10 deg modulo symmetry).
fn assert_detected(scene_name: &str, model_name: &str, seeds: std::ops::Range<u64>) {
    let s = scene(scene_name);
    let m = model(model_name);
    let (_, truth) = eval::truth_pose(&s, &m).expect("the scene holds the object");
    let symmetry = Symmetry::of(&m);
    for seed in seeds {
        let t = eval::trial(
            &s,
            &m,
            Some(&truth),
            &symmetry,
            seed,
            &Params {
                seed,
                ..Params::default()
            },
        );
        assert!(
            t.correct,
            "{model_name} in {scene_name}, seed {seed}: found {}, position error {:.4} m, rotation error {:.2} deg",
            t.found,
            t.position_error,
            t.rotation_error.to_degrees()
        );
    }
}

#[test]
fn finds_the_bowl_among_two_bowls() {
    assert_detected("fig3_table.toml", "bowl", 0..3);
}

#[test]
fn finds_the_partly_hidden_cup_in_six_dof() {
    assert_detected("fig3_table.toml", "cup", 0..3);
}

#[test]
fn finds_the_cup_body_in_five_dof() {
    assert_detected("fig3_table.toml", "cup_body", 0..3);
}

#[test]
fn finds_the_mallet_among_lookalike_tools() {
    assert_detected("fig4_tools.toml", "mallet", 0..3);
}

/// A mug standing on a book (`scenes/stacked/mug_on_book.toml`): the book's top around the
/// mug's base, just outside its wall, once counted as the mug's surface going on past its edge
/// and failed it (as the mug on the biscuit tin of mOSD test32).
#[test]
fn the_mug_on_the_book() {
    assert_detected("stacked/mug_on_book.toml", "mug", 1..4);
}

/// The white bowl upside down with a can standing on its base: the base test, which tells an
/// upturned vessel from a closed can by the middle of its base, cannot see that middle and once
/// refused the bowl for it (as under the tower of mOSD test42).
#[test]
fn the_upside_down_bowl_under_the_can() {
    assert_detected("stacked/mug_on_book.toml", "white_bowl", 1..4);
    assert_detected("stacked/mug_on_book.toml", "learned_cylinder", 1..4);
}

/// The white bowl standing on an upturned pot: the pot's base around the bowl's foot once
/// failed its shell test (as on the yellow pot of mOSD test60).
#[test]
fn the_bowl_on_the_pot() {
    assert_detected("stacked/bowl_on_pot.toml", "white_bowl", 1..4);
}

/// A can lying across a flat tin, 80 mm above the table.
#[test]
fn a_can_lying_across_a_tin() {
    assert_detected("stacked/bowl_on_pot.toml", "learned_cylinder", 1..4);
}

/// Two boxes of one shape side by side, one the learned box and the other 30 % larger: the
/// learned box is found once, and not on the larger one.
#[test]
fn the_learned_box_is_not_the_larger_one_beside_it() {
    let s = scene("stacked/bowl_on_pot.toml");
    let m = model("learned_box");
    let (_, truth) = eval::truth_pose(&s, &m).unwrap();
    for seed in 1..4 {
        let sweep = simulate(&s, seed);
        let params = Params {
            seed,
            all: true,
            viewpoint: sweep.cloud.viewpoint_position(),
            ..Params::default()
        };
        let report = detect(&sweep.cloud.points, &m, &params);
        let found: Vec<_> = report.detections.iter().filter(|d| d.found).collect();
        assert_eq!(found.len(), 1, "seed {seed}: {found:?}");
        let off = (found[0].pose.translation.vector - truth.translation.vector).norm();
        assert!(off < 0.01, "seed {seed}: {off} m from the learned box");
    }
}

#[test]
fn says_not_here_when_the_object_is_absent() {
    for (scene_name, model_name, object) in [
        ("fig3_table.toml", "bowl", "ceramic_bowl"),
        ("fig3_table.toml", "cup", "cup"),
        ("fig4_tools.toml", "mallet", "mallet"),
    ] {
        let s = scene(scene_name).without_object(object);
        let m = model(model_name);
        for seed in 0..2 {
            let t = eval::trial(
                &s,
                &m,
                None,
                &Symmetry::of(&m),
                seed,
                &Params {
                    seed,
                    ..Params::default()
                },
            );
            assert!(
                !t.found,
                "{model_name} reported found in {scene_name} without {object} (seed {seed})"
            );
            let conf = t.report.detections.first().map_or(0.0, |d| d.confidence);
            assert!(conf < 0.5, "confidence {conf} for an absent {model_name}");
        }
    }
}

#[test]
fn same_seed_same_answer() {
    let s = scene("fig3_table.toml");
    let sweep = simulate(&s, 4);
    let m = model("cup");
    let params = Params {
        seed: 9,
        viewpoint: sweep.cloud.viewpoint_position(),
        ..Params::default()
    };
    let a = detect(&sweep.cloud.points, &m, &params);
    let b = detect(&sweep.cloud.points, &m, &params);
    let pose = |r: &sqscan::detect::Report| {
        let d = r.detections.first().expect("a candidate");
        (
            d.pose.translation.vector.map(f64::to_bits),
            d.pose.rotation.coords.map(f64::to_bits),
            d.found,
        )
    };
    assert_eq!(pose(&a), pose(&b));
}

#[test]
fn all_instances_are_reported_once_each() {
    // Two mugs side by side: --all gives both, and neither twice.
    let text = std::fs::read_to_string(root().join("scenes/fig3_table.toml")).unwrap();
    let text = format!(
        "{text}\n[[object]]\nname = \"mug_a\"\nmodel = \"mug\"\npose = {{ position = [0.70, 0.30, 0.0] }}\n\
         [[object]]\nname = \"mug_b\"\nmodel = \"mug\"\npose = {{ position = [0.72, -0.16, 0.0] }}\n"
    );
    let s = Scene::from_toml_str(&text, Path::new("two_mugs.toml"), &root().join("models")).unwrap();
    let sweep = simulate(&s, 1);
    let m = model("mug");
    let params = Params {
        seed: 1,
        all: true,
        viewpoint: sweep.cloud.viewpoint_position(),
        ..Params::default()
    };
    let report = detect(&sweep.cloud.points, &m, &params);
    // The scene's cup is a closed cylinder of nearly the mug's size: what a mug on its rim
    // shows, but with a flat top where a mug's base is raised inside its foot ring. It is not
    // a mug; the two mugs standing on their bases are the only answers.
    for d in &report.detections {
        assert_eq!(d.upright, Some(true), "an answer that is not a mug standing: {d}");
    }
    let mut found: Vec<[f64; 2]> = report
        .detections
        .iter()
        .filter(|d| d.upright == Some(true))
        .map(|d| [d.pose.translation.x, d.pose.translation.y])
        .collect();
    found.sort_by(|a, b| a[1].total_cmp(&b[1]));
    assert_eq!(found.len(), 2, "instances {found:?}");
    assert!(
        (found[0][0] - 0.72).abs() < 0.01 && (found[0][1] + 0.16).abs() < 0.01,
        "{found:?}"
    );
    assert!(
        (found[1][0] - 0.70).abs() < 0.01 && (found[1][1] - 0.30).abs() < 0.01,
        "{found:?}"
    );
}

#[test]
fn degenerate_clouds_give_an_answer_not_a_panic() {
    let m = model("cup");
    let p = Params::default();
    for cloud in [
        vec![],
        vec![[f32::NAN; 3]; 1000],
        vec![[0.5f32, 0.1, 0.7]; 500],
        vec![[1e30f32, -1e30, 1e30]; 200],
    ] {
        let r = detect(&cloud, &m, &p);
        assert!(r.best_found().is_none());
    }
}

/// A sweep of 4096 columns (600k points, rows a fifth of a millimetre apart) is thinned along
/// its rows before the search, and the bowl is still found where it is; the report still counts
/// every point the sweep measured.
#[test]
fn a_4096_column_sweep_is_thinned_and_the_bowl_found() {
    let text = std::fs::read_to_string(root().join("scenes/fig3_table.toml")).unwrap();
    let text = text.replace("columns = 256", "columns = 4096");
    let s = Scene::from_toml_str(&text, Path::new("fig3_4096.toml"), &root().join("models")).unwrap();
    let m = model("bowl");
    let (_, truth) = eval::truth_pose(&s, &m).expect("the scene holds the bowl");
    let sweep = simulate(&s, 0);
    let params = Params {
        viewpoint: sweep.cloud.viewpoint_position(),
        ..Params::default()
    };
    let r = detect(&sweep.cloud.points, &m, &params);
    let finite = sweep
        .cloud
        .points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .count();
    assert!(finite > 500_000, "{finite} points");
    assert_eq!(r.points, finite);
    let d = r.detections.iter().find(|d| d.found).expect("the bowl is found");
    let error = (d.pose.translation.vector - truth.translation.vector).norm();
    assert!(error < 0.01, "position error {error:.4} m");
}

/// `sqscan detect --repeat` runs the same detection in one process and gives the same answer as
/// one run (a real scan, the mug); a count of runs outside 1..=1000 is refused by name.
#[test]
fn repeated_detections_in_one_process_give_one_answer() {
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_sqscan"))
            .args(["detect", "--model", "mug", "--seed", "5", "--models-dir"])
            .arg(root().join("models"))
            .arg("--cloud")
            .arg(root().join("tests/data/real/learn33.pcd"))
            .args(extra)
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let answer = |json: &str| {
        let mut v: serde_json::Value = serde_json::from_str(json.trim()).unwrap();
        v.as_object_mut().unwrap().remove("timing_ms");
        v
    };
    let (ok, once, err) = run(&[]);
    assert!(ok, "{err}");
    let (ok, thrice, err) = run(&["--repeat", "3"]);
    assert!(ok, "{err}");
    assert_eq!(answer(&once), answer(&thrice));
    assert_eq!(answer(&once)["found"], true);
    for bad in ["0", "1001"] {
        let (ok, _, err) = run(&["--repeat", bad]);
        assert!(!ok && err.contains("--repeat"), "{bad}: {err}");
    }
}

/// A compound's single answer is the first of its answers with `all`: without `all` the parts
/// are first placed by the connections alone, the candidates are refined a few at a time and
/// the search stops at the first that passes; with it, every combination of the whole search is
/// judged. The rigid refinement brings both to the same pose, to its convergence (it starts
/// from placements a fraction of a millimetre apart; they end a nanometre apart at most). The
/// single answer is the same to the bit whatever the number of threads (how many candidates
/// are refined at a time).
#[test]
fn a_compound_answer_is_the_first_of_all_on_any_number_of_threads() {
    let s = scene("fig4_tools.toml");
    let m = model("mallet");
    let apart = |a: &sqscan::detect::Report, b: &sqscan::detect::Report| {
        let (a, b) = (&a.detections[0], &b.detections[0]);
        assert_eq!(a.found, b.found);
        assert!(
            (a.confidence - b.confidence).abs() < 1e-6,
            "{} {}",
            a.confidence,
            b.confidence
        );
        (
            (a.pose.translation.vector - b.pose.translation.vector).norm(),
            a.pose.rotation.angle_to(&b.pose.rotation),
        )
    };
    let key = |r: &sqscan::detect::Report| {
        r.detections.first().map(|d| {
            (
                d.pose.translation.vector.map(f64::to_bits),
                d.pose.rotation.coords.map(f64::to_bits),
                d.found,
                d.confidence.to_bits(),
            )
        })
    };
    let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    for seed in [1, 2, 3] {
        let sweep = simulate(&s, seed);
        let params = Params {
            seed,
            viewpoint: sweep.cloud.viewpoint_position(),
            ..Params::default()
        };
        let single = detect(&sweep.cloud.points, &m, &params);
        assert!(single.detections[0].found, "seed {seed}");
        let every = detect(
            &sweep.cloud.points,
            &m,
            &Params {
                all: true,
                ..params.clone()
            },
        );
        let (moved, turned) = apart(&single, &every);
        assert!(
            moved < 1e-6 && turned < 1e-6,
            "seed {seed}: {moved} m, {turned} rad apart"
        );
        let serial = one_thread.install(|| detect(&sweep.cloud.points, &m, &params));
        assert_eq!(key(&single), key(&serial), "seed {seed}");
    }
}
