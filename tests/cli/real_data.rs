//! The detector on real scans nobody here made (`tests/data/real`, see its SOURCES.md): the
//! mOSD table scenes carry per-point labels for each mug and bowl. The detector, with the shipped
//! mug and bowl models (sized from these scans), must land on a labelled mug or bowl: its centre
//! within 4 cm of the centre of that object's labelled points. These are camera-frame clouds from
//! a Kinect-type sensor: nothing of our rig is assumed (the viewpoint is the camera origin).

use nalgebra::{Point3, Vector3};
use sqscan::cloud::{FieldData, PointCloud, read_cloud};
use sqscan::detect::{Params, detect};
use sqscan::model::Model;
use std::path::{Path, PathBuf};

use crate::common::real_data as data;

/// Centroids of the labelled objects `label / 10` in `objects`.
fn centroids(cloud: &PointCloud, objects: &[u32]) -> Vec<(u32, Point3<f64>)> {
    let labels = match cloud.field("label").map(|f| &f.data) {
        Some(FieldData::U32(l)) => l,
        _ => panic!("no uint label field"),
    };
    objects
        .iter()
        .map(|&o| {
            let mut sum = Vector3::zeros();
            let mut n = 0.0;
            for (p, &l) in cloud.points.iter().zip(labels) {
                if l >= 20 && l / 10 == o && p.iter().all(|v| v.is_finite()) {
                    sum += Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                    n += 1.0;
                }
            }
            assert!(n > 100.0, "object {o} has {n} labelled points");
            (o, Point3::from(sum / n))
        })
        .collect()
}

fn model(name: &str) -> Model {
    Model::load(name, &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap()
}

/// The best detection of `model_name` in `file` lies within 4 cm of one of `objects`.
fn lands_on(file: &str, model_name: &str, objects: &[u32]) {
    let cloud = read_cloud(&data(file)).unwrap();
    let targets = centroids(&cloud, objects);
    let params = Params {
        viewpoint: Some(Point3::origin()),
        ..Params::default()
    };
    let report = detect(&cloud.points, &model(model_name), &params);
    let best = report
        .best_found()
        .unwrap_or_else(|| panic!("{model_name} not found in {file}"));
    let c = Point3::from(best.pose.translation.vector);
    let (obj, d) = targets
        .iter()
        .map(|(o, t)| (*o, (t - c).norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert!(
        d < 0.04,
        "{model_name} in {file}: detected at {c:?}, {d:.3} m from the nearest labelled target (object {obj})"
    );
}

#[test]
fn mug_in_learn33_lands_on_a_labelled_mug() {
    lands_on("learn33.pcd", "mug", &[5, 6]);
}

#[test]
fn mug_in_test34_lands_on_a_labelled_mug() {
    lands_on("test34.pcd", "mug", &[5, 6]);
}

/// test64's mug stands among canisters and cartons: the mug model also fits one end of a capped
/// canister twice its height, and did better there (fit and lid points) until the check for a
/// wall continuing past an open part's ends (`verify::beyond_the_ends`). Over search seeds 0-4
/// the detector lands on the labelled mug in 4 (BENCHMARKS.md); once it settles on a tilted
/// lookalike. The test asks for the default seed and for a majority of the five.
#[test]
fn mug_in_test64_lands_on_the_labelled_mug() {
    lands_on("test64.pcd", "mug", &[3]);
    let cloud = read_cloud(&data("test64.pcd")).unwrap();
    let targets = centroids(&cloud, &[3]);
    let mug = model("mug");
    let hits = (0..5u64)
        .filter(|&seed| {
            let params = Params {
                seed,
                viewpoint: Some(Point3::origin()),
                ..Params::default()
            };
            let report = detect(&cloud.points, &mug, &params);
            let d = report
                .best_found()
                .map(|d| (targets[0].1 - Point3::from(d.pose.translation.vector)).norm());
            eprintln!("test64 mug, seed {seed}: {d:?} m from the labelled mug's centre");
            d.is_some_and(|d| d < 0.04)
        })
        .count();
    assert!(hits >= 3, "the mug in test64 found in {hits} of 5 seeds");
}

#[test]
fn white_bowl_in_learn33_lands_on_the_labelled_bowl() {
    lands_on("learn33.pcd", "white_bowl", &[4]);
}

#[test]
fn large_wooden_bowl_in_test64_lands_on_the_labelled_bowl() {
    lands_on("test64.pcd", "large_wooden_bowl", &[5]);
}

#[test]
fn the_pcl_mug_scene_gives_the_tutorial_table_and_an_upright_mug_on_its_axis() {
    // PCL's cylinder_segmentation tutorial on this file (after a z < 1.5 m cut): table plane
    // (-0.0161854, 0.837724, 0.545855, -0.528787); mug axis through (0.0452, 0.0925, 0.7902)
    // along (0.2050, -0.7216, -0.6612), radius 0.0396 m. No ground truth: PCL's RANSAC cylinder
    // is the reference.
    let cloud = read_cloud(&data("table_scene_mug_stereo_textured.pcd")).unwrap();
    let params = Params {
        viewpoint: Some(Point3::origin()),
        max_range: Some(1.5),
        ..Params::default()
    };
    let report = detect(&cloud.points, &model("mug"), &params);
    let plane = report.plane.expect("the table");
    let pcl = Vector3::new(-0.0161854, 0.837724, 0.545855);
    assert!(plane.normal.dot(&pcl).abs() > 0.9999, "plane normal {:?}", plane.normal);
    assert!((plane.d.abs() - 0.528787).abs() < 0.003, "plane offset {}", plane.d);
    let best = report.best_found().expect("the mug");
    let c = best.pose.translation.vector;
    let p0 = Vector3::new(0.0452, 0.0925, 0.7902);
    let axis = Vector3::new(0.2050, -0.7216, -0.6612).normalize();
    let off_axis = ((c - p0) - axis * (c - p0).dot(&axis)).norm();
    assert!(
        off_axis < 0.01,
        "detected centre {c:?} is {off_axis:.4} m off PCL's cylinder axis"
    );
    // Our mug stands on the table: its axis is the table normal.
    let z = best.pose.rotation * Vector3::z();
    assert!(
        z.dot(&plane.normal).abs() > 0.98,
        "mug axis {z:?} vs table normal {:?}",
        plane.normal
    );
}

/// Every instance asked for, at `seed`, from the camera-frame sensor at the origin.
fn every_instance(seed: u64) -> Params {
    Params {
        seed,
        all: true,
        viewpoint: Some(Point3::origin()),
        ..Params::default()
    }
}

/// Where `model` is found in `cloud` (`--all`, search seed `seed`) within `radius` of `at`, with
/// the confidences.
fn found_near(cloud: &PointCloud, model: &Model, seed: u64, at: Point3<f64>, radius: f64) -> Vec<(Point3<f64>, f64)> {
    detect(&cloud.points, model, &every_instance(seed))
        .detections
        .iter()
        .filter(|d| d.found)
        .map(|d| (Point3::from(d.pose.translation.vector), d.confidence))
        .filter(|(p, _)| (p - at).norm() < radius)
        .collect()
}

/// With every instance asked for, over search seeds 0-3, the mug is found nowhere in `file`: a
/// scene with no mug in it.
fn no_mug_in(file: &str) {
    let cloud = read_cloud(&data(file)).unwrap();
    let mug = model("mug");
    for seed in 0..4u64 {
        let report = detect(&cloud.points, &mug, &every_instance(seed));
        let found: Vec<_> = report
            .detections
            .iter()
            .filter(|d| d.found)
            .map(|d| (d.pose.translation.vector, d.upright, d.confidence))
            .collect();
        assert!(found.is_empty(), "{file}, seed {seed}: a mug found at {found:?}");
    }
}

/// mOSD learn8: a small tea box peeks over a cereal box. The mug, on its rim, was fitted to the
/// box's top: two flat faces and a corner that the noise of a Kinect at 0.7 m let pass as a
/// round wall. Now the wall's cross-section must be rounder than two straight lines
/// (`verify::flat_faces`) and nothing may lie above a container's top.
#[test]
fn mug_is_not_the_tea_box() {
    no_mug_in("learn8.pcd");
}

/// mOSD learn30: a Pringles can lies on its side behind a grey block. A mug laid on its side
/// fitted each end of the can. A container rests on its base or its rim
/// (`search::MAX_REST_TILT`).
#[test]
fn mug_is_not_the_lying_can() {
    no_mug_in("learn30.pcd");
}

/// mOSD learn40: a small lidded canister, the size of the mug to a millimetre, stands on the
/// table. Upside down, a mug shows the same closed cylinder, and the mug on its rim was found on
/// it. A container on its rim now needs the base of a vessel at its top: the middle below its
/// foot ring (`accept::MIN_BASE_RECESS`); the canister's lid is flat.
#[test]
fn mug_is_not_the_lidded_canister() {
    no_mug_in("learn40.pcd");
}

/// With every instance asked for, at each of `seeds`, `model_name` is found within 5 cm of each
/// labelled object of `file`, standing the given way up.
fn found_standing(file: &str, model_name: &str, objects: &[u32], upright: bool, seeds: std::ops::Range<u64>) {
    found_standing_as(file, &model(model_name), objects, upright, seeds);
}

/// [`found_standing`] with a model at hand.
fn found_standing_as(file: &str, m: &Model, objects: &[u32], upright: bool, seeds: std::ops::Range<u64>) {
    let model_name = &m.name;
    let cloud = read_cloud(&data(file)).unwrap();
    let targets = centroids(&cloud, objects);
    for seed in seeds {
        let report = detect(&cloud.points, m, &every_instance(seed));
        for (o, t) in &targets {
            let hit = report
                .detections
                .iter()
                .filter(|d| d.found)
                .find(|d| (t - Point3::from(d.pose.translation.vector)).norm() < 0.05)
                .unwrap_or_else(|| panic!("{file}, seed {seed}: the {model_name} {o} is not found"));
            assert_eq!(
                hit.upright,
                Some(upright),
                "{file}, seed {seed}: {model_name} {o} stands the wrong way up"
            );
        }
    }
}

/// mOSD learn38: two white mugs stand upside down, on their rims, their handles hidden. Both are
/// found, by their bases, and both are flagged as standing on their rims.
#[test]
fn upside_down_mugs_are_found_and_flagged() {
    found_standing("learn38.pcd", "mug", &[2, 3], false, 5..6);
}

/// mOSD learn34: the white bowl stands close to the sensor, which sees mostly its inside. Trials
/// started the shape behind every patch, as for a convex surface; a patch of the inner wall or
/// bottom has the bowl's centre in front of it, and the bowl was missed at 2 of the 10 seeds.
#[test]
fn white_bowl_seen_from_inside_is_found() {
    found_standing("learn34.pcd", "white_bowl", &[4], true, 0..10);
}

/// mOSD learn37: the white bowl stands upside down. Its base was looked for over the model's
/// middle section, which for a rounded, tapered end reaches past the foot down the sloping wall
/// and read as a dome (-8 mm); measured across the foot, the base is recessed as a vessel's is.
#[test]
fn upside_down_white_bowl_is_found_by_its_foot() {
    found_standing("learn37.pcd", "white_bowl", &[3], false, 0..3);
}

/// mOSD learn40: the yellow pot stands upside down. Its model, as `sqscan learn` takes it from
/// the pot standing upright in mOSD learn36, is 109 mm tall where the pot's wall is 102 mm: a
/// trial fitted to a patch of its base and wall reached 10-15 mm through the table, past what
/// the plane allows, and every trial on the pot was thrown away. Set on the table, they find it.
#[test]
fn the_upturned_pot_is_found_though_its_model_stands_taller() {
    let m = Model::from_toml_str(
        "name = \"yellow_pot\"\n[[part]]\nname = \"body\"\na = [0.0857, 0.0857, 0.0544]\ne1 = 0.181818\ne2 = 1.0\nopen = true\n",
        Path::new("yellow_pot.toml"),
    )
    .unwrap();
    found_standing_as("learn40.pcd", &m, &[4], false, 0..3);
}

/// The model `sqscan learn` writes from object `label` of the carried scan `file`, loaded.
fn learned_from(file: &str, label: u32, name: &str) -> Model {
    let dir = std::env::temp_dir().join(format!("sqscan-learned-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sqscan"))
        .args(["learn", "--cloud"])
        .arg(data(file))
        .args(["--label", &label.to_string(), "--name", name, "--force", "--out"])
        .arg(dir.join(format!("{name}.toml")))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m = Model::load(name, &dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    m
}

/// The white bowl learned from mOSD learn33 finds the white bowl of learn34 upright and of
/// learn37 upside down. Fitted as one closed shape to what the sensor saw of both of its walls
/// (and without its near wall, which the segmentation dropped as a cluster of its own 31 mm
/// away seen from above) it came out 5-10 mm too narrow and found neither; its outer wall's
/// profile gives its size.
#[test]
fn white_bowl_learned_from_one_scan_is_found_both_ways_up() {
    let m = learned_from("learn33.pcd", 4, "learned_white_bowl");
    found_standing_as("learn34.pcd", &m, &[4], true, 5..6);
    found_standing_as("learn37.pcd", &m, &[3], false, 5..6);
}

/// The mug learned from mOSD test34 is round, of the radius its outer wall shows (it was an oval
/// of 42 by 35 mm, its near wall and a handle's root fitted as one closed shape with its inside),
/// and finds both mugs standing upside down in learn38: the same plain white mug, and the
/// printed one, 7 mm shorter. On that one the model, fitted to its base, reached 13.9 mm
/// through the table and was dropped instead of being set on it; set on it, its base's recess
/// read 0.9 mm across 65-88 % of the model's foot, where the mug's foot ring lies beyond.
#[test]
fn mug_learned_from_one_scan_is_found_upside_down() {
    let m = learned_from("test34.pcd", 5, "learned_mug");
    found_standing_as("learn38.pcd", &m, &[2, 3], false, 5..6);
}

/// mOSD learn2: the gittis muesli box standing, its narrow side and its top in view. Its first
/// fit's centre fell off to a corner, the top's points outside the fit's inner half, and the box
/// was learned as an open round pot that was found nowhere. Measured from its top it is a closed
/// box of its size (its top's points: about 48 by 125 mm, 214 mm above the table).
#[test]
fn the_gittis_box_is_learned_as_a_box() {
    let m = learned_from("learn2.pcd", 2, "learned_gittis_box");
    let part = &m.parts[0];
    assert!(!part.open, "{:?}", part.shape);
    assert!(part.shape.e2 < 0.3 && part.shape.e1 < 0.3, "{:?}", part.shape);
    let mut full = part.shape.a.map(|a| 2.0 * a);
    full.sort_by(f64::total_cmp);
    for (got, want) in full.iter().zip([0.048, 0.125, 0.214]) {
        assert!((got - want).abs() < 0.1 * want, "sizes {full:?}");
    }
}

/// mOSD test44: the floral canister stands on a cereal box lying flat (object 6), the Vitalis box
/// on the biscuit tin (object 4). Fitted resting on the table, their models took the height of
/// what they stand on as their own (the canister 84 x 84 x 167 mm, the Vitalis box 261 mm tall);
/// resting on the top round their feet, they are their own size: the canister about 83 x 83 x
/// 104 mm (as learned from learn40, where it stands on the table), the Vitalis box 200 mm tall
/// (its height upside down on the table in mOSD test6).
#[test]
fn objects_standing_on_others_are_learned_their_own_height() {
    let canister = learned_from("test44.pcd", 6, "learned_canister_on_box");
    let mut full = canister.parts[0].shape.a.map(|a| 2.0 * a);
    full.sort_by(f64::total_cmp);
    for (got, want) in full.iter().zip([0.083, 0.083, 0.104]) {
        assert!((got - want).abs() < 0.1 * want, "canister sizes {full:?}");
    }
    let vitalis = learned_from("test44.pcd", 4, "learned_vitalis_on_tin");
    let tallest = vitalis.parts[0].shape.a.iter().fold(0.0f64, |m, a| m.max(2.0 * a));
    assert!(
        (tallest - 0.2).abs() < 0.1 * 0.2,
        "Vitalis box {:?}",
        vitalis.parts[0].shape.a
    );
}

/// The tea box as `sqscan learn` learned it from mOSD learn6 (62 x 78 x 148 mm).
const LEARNED_TEA_BOX: &str =
    "name = \"tea_box\"\n[[part]]\nname = \"body\"\na = [0.031, 0.0391, 0.0738]\ne1 = 0.1\ne2 = 0.1\n";

/// The tea box's model once answered on the upper part of the gittis box standing in mOSD
/// learn3 (47 x 127 x 212 mm): it shared the box's top and the upper part of its front, and the
/// front going on in its plane below the model's lower edge reached past the shell's first
/// millimetres only. Over seeds 0-3 no answer lies on the gittis box (object 2); that box's own
/// model, learned from learn2, is found there.
#[test]
fn the_tea_box_is_not_found_in_the_gittis_box() {
    let cloud = read_cloud(&data("learn3.pcd")).unwrap();
    let gittis = centroids(&cloud, &[2])[0].1;
    let near_it = |m: &Model, seed: u64| found_near(&cloud, m, seed, gittis, 0.05);
    let tea = Model::from_toml_str(LEARNED_TEA_BOX, std::path::Path::new("tea_box.toml")).unwrap();
    for seed in 0..4u64 {
        let on_it = near_it(&tea, seed);
        assert!(
            on_it.is_empty(),
            "seed {seed}: the tea box found on the gittis box at {on_it:?}"
        );
    }
    let gittis_model = learned_from("learn2.pcd", 2, "learned_gittis_box_3");
    assert!(
        !near_it(&gittis_model, 5).is_empty(),
        "the gittis box's own model does not find it"
    );
}

/// mOSD learn8: the tea box stands behind the Toppas box, which hides its lower part. Its
/// model was answered lying across it (at seeds 0 and 5), a box 148 mm long reaching 70 mm into space the
/// sensor saw the table through beside it (a fifth of its visible side); the free-space test took
/// the share of the side seen through only, not how far from the seen part it lay. Over seeds
/// 0-9 every answer near the tea box (object 3) stands, and there is one at seed 5.
#[test]
fn the_tea_box_standing_is_not_answered_lying_across_free_space() {
    let cloud = read_cloud(&data("learn8.pcd")).unwrap();
    let tea_box = centroids(&cloud, &[3])[0].1;
    let tea = Model::from_toml_str(LEARNED_TEA_BOX, std::path::Path::new("tea_box.toml")).unwrap();
    for seed in 0..10u64 {
        let report = detect(&cloud.points, &tea, &every_instance(seed));
        let normal = report.plane.as_ref().expect("the table is found").normal;
        let near: Vec<f64> = report
            .detections
            .iter()
            .filter(|d| d.found && (Point3::from(d.pose.translation.vector) - tea_box).norm() < 0.1)
            .map(|d| (d.pose.rotation * Vector3::z()).dot(&normal).abs())
            .collect();
        assert!(
            near.iter().all(|&c| c > 0.95),
            "seed {seed}: the tea box answered with its long axis at cosines {near:?} to the table's normal"
        );
        assert!(
            seed != 5 || !near.is_empty(),
            "seed 5: the standing tea box is not found"
        );
    }
}

/// The Weetabix box as learned from mOSD learn28 (`sqscan learn --label 2`): 52 x 180 x 261 mm.
const LEARNED_WEETABIX_BOX: &str =
    "name = \"weetabix_box\"\n[[part]]\nname = \"body\"\na = [0.026, 0.09, 0.1304]\ne1 = 0.1\ne2 = 0.1\n";

/// In mOSD test8 the Weetabix box (object 3) lies flat behind the gittis box standing in front of
/// it, which hides more than half of its top: its best placement covered 41 % of its visible
/// side, short of the 45 % the acceptance test asks, and it was not found. The surface another
/// object hides now counts where the rest of the side, where the sensor could see it, was seen.
/// Over seeds 0-4 it is found there and never on the gittis box (object 2); with hidden surface
/// not counted, not at seed 5.
#[test]
fn the_weetabix_box_half_hidden_behind_the_gittis_box_is_found() {
    let cloud = read_cloud(&data("test8.pcd")).unwrap();
    let at = centroids(&cloud, &[2, 3]);
    let (gittis, weetabix) = (at[0].1, at[1].1);
    let model = Model::from_toml_str(LEARNED_WEETABIX_BOX, std::path::Path::new("weetabix_box.toml")).unwrap();
    let found_near = |params: &Params, p: Point3<f64>| {
        detect(&cloud.points, &model, params)
            .detections
            .iter()
            .filter(|d| d.found && (Point3::from(d.pose.translation.vector) - p).norm() < 0.05)
            .count()
    };
    for seed in 0..5u64 {
        assert!(
            found_near(&every_instance(seed), weetabix) > 0,
            "seed {seed}: not found"
        );
        assert_eq!(
            found_near(&every_instance(seed), gittis),
            0,
            "seed {seed}: on the gittis box"
        );
    }
    let mut hidden_not_counted = every_instance(5);
    hidden_not_counted.acceptance.min_coverage_hidden = 1.0;
    assert_eq!(found_near(&hidden_not_counted, weetabix), 0);
}

/// In mOSD learn21 the Weetabix box (object 2) lies flat at the bottom of a stack, under the
/// Toppas box (3) with the gittis box (4) on top: the sensor sees its front walls, a 5 cm strip,
/// and a strip of its top. The trials' fits there were drawn onto the boxes above, and it was
/// found at four of the search seeds 0-7; the poses resting on the table that its walls place
/// find it at every one, and never on the boxes above it.
#[test]
fn the_weetabix_box_at_the_bottom_of_a_stack_is_found_from_its_walls() {
    let cloud = read_cloud(&data("learn21.pcd")).unwrap();
    let at = centroids(&cloud, &[2, 3, 4]);
    let model = Model::from_toml_str(LEARNED_WEETABIX_BOX, std::path::Path::new("weetabix_box.toml")).unwrap();
    for seed in 0..8u64 {
        let found: Vec<Point3<f64>> = detect(&cloud.points, &model, &every_instance(seed))
            .detections
            .iter()
            .filter(|d| d.found)
            .map(|d| Point3::from(d.pose.translation.vector))
            .collect();
        assert!(!found.is_empty(), "seed {seed}: not found");
        for p in &found {
            let nearest = at
                .iter()
                .min_by(|a, b| (a.1 - p).norm().total_cmp(&(b.1 - p).norm()))
                .unwrap();
            assert_eq!(nearest.0, 2, "seed {seed}: an answer at {p} is on object {}", nearest.0);
            assert!(
                (nearest.1 - p).norm() < 0.08,
                "seed {seed}: an answer at {p} is off the box"
            );
        }
    }
}

/// The gittis box as learned from mOSD learn2 (`sqscan learn --label 2`): 46 x 123 x 212 mm.
const LEARNED_GITTIS_BOX: &str =
    "name = \"gittis_box\"\n[[part]]\nname = \"body\"\na = [0.0232, 0.0614, 0.1059]\ne1 = 0.1\ne2 = 0.1\n";

/// In mOSD test44 the Vitalis box (object 4) stands on the biscuit tin (object 2). The gittis
/// box's model, taller than the Vitalis box, fits it with its top on the Vitalis box's top and
/// its foot 3 cm down inside the tin: standing on nothing. A whole object rests on the table or
/// on something level at its foot, and the model is not found there at any search seed 0-7.
#[test]
fn the_gittis_box_is_not_found_on_the_box_standing_on_the_tin() {
    let cloud = read_cloud(&data("test44.pcd")).unwrap();
    let vitalis = centroids(&cloud, &[4])[0].1;
    let model = Model::from_toml_str(LEARNED_GITTIS_BOX, std::path::Path::new("gittis_box.toml")).unwrap();
    for seed in 0..8u64 {
        let on_it = found_near(&cloud, &model, seed, vitalis, 0.08);
        assert!(on_it.is_empty(), "seed {seed}: found on the Vitalis box at {on_it:?}");
    }
}
