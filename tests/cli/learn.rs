//! A model learned from a simulated single-object scan (fig3 rig, 2 mm noise at 1 m): sizes
//! within 5 mm and e1, e2 within 0.1 of the truth, after matching the learned axes to the true
//! ones (symmetric equivalents compare equal), for the hardest shipped single-part model of each
//! kind (`benches/learn_table.sh` measures all of them); compounds, several sweeps, real scans.

use sqscan::learn::LearnParams;
use sqscan::learn::simulated::learn_simulated;
use sqscan::model::Model;
use std::path::PathBuf;

fn model(name: &str) -> Model {
    Model::load(name, &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models")).unwrap()
}

fn check(name: &str, sweeps: usize) {
    let m = model(name);
    let t = learn_simulated(&m, None, 1, sweeps, &LearnParams::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    let r = &t.learned.parts[0];
    eprintln!(
        "{name}: truth {} | learned {} | da {:?} de1 {:.3} de2 {:.3} centre {:.4} | {} pts, {} object, rms {:.2} mm, start {}, open {}, {:.2} s",
        t.truth.shape,
        r.placed.shape,
        t.errors.da.map(|d| (d * 1e4).round() / 10.0),
        t.errors.de1,
        t.errors.de2,
        t.errors.centre,
        t.points,
        t.learned.object_points,
        r.rms * 1e3,
        r.start,
        r.open,
        t.seconds
    );
    assert!(
        t.errors.max_size_error() < 0.005 && t.errors.max_exponent_error() < 0.1,
        "{name}: size errors {:?} m, e1 {:+.3}, e2 {:+.3}",
        t.errors.da,
        t.errors.de1,
        t.errors.de2
    );
}

macro_rules! cases {
    ($($name:ident),*) => {
        $(#[test]
        fn $name() {
            check(stringify!($name), 1);
        })*
    };
}

// Within 5 mm and 0.1 from one sweep. All 13 shipped single-part models meet this
// (`benches/learn_table.sh 1`; BENCHMARKS.md, "Learning models", has every model's numbers,
// seeds 1-3); the tests keep the hardest of each kind, so that the suite stays short: the two
// rods lying on their side (the largest errors), the tapered bowl (stands on its narrow end:
// the flipped-taper starts), the open mug and the open, tapered white bowl (seen through their
// openings), the mouse (a general shape, not of revolution, with tapers of the other sign) and
// the ball (e1 = e2 = 1: any axis is its z). The box is `a_carton_seen_at_its_corner_is_a_box`.
cases!(ball, bowl, mallet_shaft, mouse, mug, pen, white_bowl);

// The pen, the rod with the largest error from one sweep, from the per-pixel median of 32 sweeps
// of the one view (`sqscan learn --cloud` with several files): the noise drops to about 0.4 mm,
// and the ends come out right. The mallet shaft does the same (BENCHMARKS.md).
#[test]
fn pen_from_32_sweeps() {
    check("pen", 32);
}

/// What `sqscan learn` writes loads as a model with the learned shape.
#[test]
fn the_written_model_loads() {
    let t = learn_simulated(&model("spray_tin"), None, 1, 1, &LearnParams::default()).unwrap();
    let prov = sqscan::learn::Provenance {
        input: "simulated spray_tin".into(),
        selection: "all".into(),
        command: "test".into(),
    };
    let text = sqscan::learn::model_toml("learned_tin", &t.learned, &prov);
    assert!(text.starts_with("# Learned by `sqscan learn`"), "{text}");
    let m = Model::from_toml_str(&text, std::path::Path::new("learned_tin.toml")).unwrap();
    assert_eq!(m.name, "learned_tin");
    assert_eq!(m.parts.len(), 1);
    let (got, fitted) = (m.parts[0].shape, t.learned.parts[0].placed.shape);
    assert!((got.a[2] - fitted.a[2]).abs() < 1e-4 && (got.e1 - fitted.e1).abs() < 1e-3);
    // A can is a body of revolution: written as one.
    assert!(got.is_revolution(), "{got}");
    // The model frame of a single part is the part's pose in the cloud, and the file says so.
    let pose = sqscan::learn::model_pose(&t.learned);
    let placed = t.learned.parts[0].placed.pose;
    assert!((pose.translation.vector - placed.translation.vector).norm() < 1e-12);
    assert!(pose.rotation.angle_to(&placed.rotation) < 1e-12);
    let c = pose.translation.vector;
    assert!(
        text.contains(&format!(
            "# model frame in the cloud: position [{:.5}, {:.5}, {:.5}]",
            c.x, c.y, c.z
        )),
        "{text}"
    );
}

/// The mug learned from the labelled white mug (object 5) of mOSD test34 (`models/learned_mug.toml`,
/// see its comment block) finds a labelled mug of learn33: its centre within 4 cm of the centroid
/// of that mug's labelled points, as tests/cli/real_data.rs asks of the shipped mug; asked for every
/// instance, it finds both of learn33's mugs.
#[test]
fn learned_mug_lands_on_a_mug_in_learn33() {
    use nalgebra::{Point3, Vector3};
    use sqscan::cloud::{FieldData, read_cloud};
    use sqscan::detect::{Params, detect};
    let cloud = read_cloud(&crate::common::real_data("learn33.pcd")).unwrap();
    let labels = match cloud.field("label").map(|f| &f.data) {
        Some(FieldData::U32(l)) => l.clone(),
        _ => panic!("no label field"),
    };
    let centroid = |o: u32| {
        let (mut s, mut n) = (Vector3::zeros(), 0.0);
        for (p, &l) in cloud.points.iter().zip(&labels) {
            if l >= 20 && l / 10 == o && p.iter().all(|v| v.is_finite()) {
                s += Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                n += 1.0;
            }
        }
        Point3::from(s / n)
    };
    let params = Params {
        viewpoint: Some(Point3::origin()),
        ..Params::default()
    };
    let report = detect(&cloud.points, &model("learned_mug"), &params);
    let best = report.best_found().expect("the learned mug is found in learn33");
    let c = Point3::from(best.pose.translation.vector);
    let d = [5, 6].map(|o| (centroid(o) - c).norm());
    eprintln!(
        "learned mug in learn33 at {c:?}: {:.3} m / {:.3} m from mugs 5 / 6",
        d[0], d[1]
    );
    assert!(d[0].min(d[1]) < 0.04, "{d:?}");
    // Asked for every instance, it finds both mugs.
    let all = detect(&cloud.points, &model("learned_mug"), &Params { all: true, ..params });
    for o in [5, 6] {
        let nearest = all
            .detections
            .iter()
            .filter(|d| d.found)
            .map(|d| (centroid(o) - Point3::from(d.pose.translation.vector)).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.04, "mug {o}: the nearest instance is {nearest:.3} m away");
    }
}

/// `parts` parts learned from one simulated sweep (noise seed 7) of the model file `path` alone
/// on the table at yaw `yaw_deg`, as the model file `sqscan learn` writes, loaded back.
fn learn_parts_of(path: &std::path::Path, models_dir: &std::path::Path, yaw_deg: f64, parts: usize) -> Model {
    use nalgebra::Point3;
    use sqscan::learn::{learn_parts, model_toml, segment, simulated::scene_toml};
    use sqscan::sim::{self, Scene};
    let text = scene_toml(path, [0.85, 0.05], [0.0, 0.0, yaw_deg]);
    let scene = Scene::from_toml_str(&text, &models_dir.join("scene.toml"), models_dir).unwrap();
    let sweep = sim::simulate(&scene, 7);
    let points: Vec<Point3<f64>> = sweep.cloud.finite_points();
    let params = LearnParams {
        viewpoint: sweep.cloud.viewpoint_position(),
        ..LearnParams::default()
    };
    let seg = segment(&points, &params);
    let learned = learn_parts(&points, seg, &params, parts).unwrap();
    assert_eq!(learned.parts.len(), parts);
    let text = model_toml("learned", &learned, &Default::default());
    eprintln!("{text}");
    Model::from_toml_str(&text, std::path::Path::new("learned.toml")).unwrap()
}

/// `--parts 2` on a simulated scan of the paper's cup with its handle in view (yaw 120 deg):
/// a body near 38 x 38 x 48 mm and a second part where the handle is, connected at about
/// 90 deg and 50 mm (the shipped cup's connectivity), written as a compound model that loads.
#[test]
fn two_parts_from_a_cup_with_its_handle_in_view() {
    let cup = model("cup");
    let m = learn_parts_of(&cup.source, std::path::Path::new("models"), 120.0, 2);
    let body = m.parts[0].shape;
    let mut a = [body.a[0], body.a[1]];
    a.sort_by(f64::total_cmp);
    assert!(
        (a[0] - 0.038).abs() < 0.005 && (a[1] - 0.038).abs() < 0.005 && (body.a[2] - 0.048).abs() < 0.005,
        "body {body}"
    );
    let c = &m.connections[0];
    assert!((c.distance - 0.050).abs() < 0.01, "centre distance {}", c.distance);
    assert!(
        (c.angle.to_degrees() - 90.0).abs() < 10.0,
        "angle {}",
        c.angle.to_degrees()
    );
}

/// `--parts 3` on a simulated pot with the cup's handle on both sides (yaw 80 deg: both in
/// view): a body near the cup's, and two parts on opposite sides, each connected at about
/// 90 deg and 50 mm. Measured: the body 43 x 40 mm (it keeps the handles' roots), the handles
/// at 56 and 58 mm (their seen shells' centres), 87 and 90 deg, 139 deg apart about the body's
/// axis (the seen shells' centres lie towards the sensor; on one side they would be less than
/// 90 deg apart).
#[test]
fn three_parts_from_a_pot_with_two_handles() {
    let dir = std::env::temp_dir().join(format!("sqscan-learn-pot-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let handle = |name: &str, x: f64, orientation: &str| {
        format!(
            "[[part]]\nname = \"{name}\"\na = [0.030, 0.023, 0.008]\ne1 = 0.5\ne2 = 1.0\npose = {{ position = [{x}, 0.0, 0.0], orientation = {orientation} }}\n"
        )
    };
    let pot = format!(
        "name = \"pot\"\n[[part]]\nname = \"body\"\na = [0.038, 0.038, 0.048]\ne1 = 0.1\ne2 = 1.0\n{}{}",
        handle("left", 0.05, "[-0.5, -0.5, -0.5, 0.5]"),
        handle("right", -0.05, "[-0.5, 0.5, 0.5, 0.5]")
    ) + "[[connection]]\nparts = [\"body\", \"left\"]\nangle_deg = 90.0\ndistance = 0.05\n"
        + "[[connection]]\nparts = [\"body\", \"right\"]\nangle_deg = 90.0\ndistance = 0.05\n";
    let path = dir.join("pot.toml");
    std::fs::write(&path, pot).unwrap();
    let m = learn_parts_of(&path, &dir, 80.0, 3);
    let body = m.parts[0].shape;
    assert!(
        (body.a[0] - 0.038).abs() < 0.006 && (body.a[1] - 0.038).abs() < 0.006 && (body.a[2] - 0.048).abs() < 0.005,
        "body {body}"
    );
    assert_eq!(m.connections.len(), 2);
    for c in &m.connections {
        assert!((c.distance - 0.050).abs() < 0.01, "centre distance {}", c.distance);
        assert!(
            (c.angle.to_degrees() - 90.0).abs() < 10.0,
            "angle {}",
            c.angle.to_degrees()
        );
    }
    // On opposite sides of the body's axis.
    let side = |k: usize| {
        let t = m.parts[k].pose_in_object.translation.vector;
        nalgebra::Vector2::new(t.x, t.y).normalize()
    };
    let apart = side(1).dot(&side(2)).clamp(-1.0, 1.0).acos().to_degrees();
    assert!(
        apart > 120.0,
        "the two handles {apart:.0} deg apart about the body's axis"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A real stereo view of a can nobody here made (robotology/find-superquadric `data/cylinder`,
/// already segmented, iCub root frame, z up): standing on the plane below its lowest points,
/// with free space just outside its silhouette from the guessed eye position, it is learned as a
/// body of revolution as wide and as tall as the view shows (`models/learned_cylinder.toml`;
/// the 1-99 % extents of its points: 59 mm deep, 60 mm wide, 213 mm tall).
#[test]
fn a_real_segmented_can_is_learned_as_a_can() {
    use nalgebra::{Point3, Vector3};
    use sqscan::learn::{learn, support_below};
    let cloud = sqscan::cloud::read_cloud(&crate::common::real_data("cylinder")).unwrap();
    let points: Vec<Point3<f64>> = cloud.finite_points();
    let up = Vector3::z();
    let params = LearnParams {
        segment: false,
        up: Some(up),
        viewpoint: Some(Point3::new(-0.05, 0.0, 0.4)),
        silhouette: true,
        plane: support_below(&points, Some(&up)),
        ..LearnParams::default()
    };
    let learned = learn(&points, &params).unwrap();
    let sq = learned.parts[0].placed.shape;
    let axis = learned.parts[0].placed.pose.rotation * Vector3::z();
    eprintln!("cylinder: {sq}, axis {axis:?}");
    assert!(axis.dot(&up).abs() > 0.98, "axis {axis:?}");
    assert!((sq.a[0] - sq.a[1]).abs() < 0.003, "{sq}");
    assert!(
        (0.057..0.070).contains(&(2.0 * sq.a[0])),
        "diameter {} m",
        2.0 * sq.a[0]
    );
    assert!((2.0 * sq.a[2] - 0.213).abs() < 0.012, "height {} m", 2.0 * sq.a[2]);
    assert!(sq.e1 < 0.2 && (sq.e2 - 1.0).abs() < 0.1, "{sq}");
}

/// `sqscan learn` with several `--cloud` files learns from their per-pixel median and says so in
/// the provenance; sweeps that are not of one view are refused with the reason.
#[test]
fn learn_from_several_sweeps_of_one_view() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_sqscan");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("sqscan-learn-sweeps-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let simulate = |seed: u64, columns: Option<u32>| {
        let out = dir.join(format!("s{seed}-{}", columns.unwrap_or(0)));
        let mut cmd = Command::new(bin);
        cmd.arg("simulate")
            .arg("--models-dir")
            .arg(root.join("models"))
            .arg(root.join("scenes/learn/cup_alone.toml"))
            .arg("--out")
            .arg(&out)
            .args(["--seed", &seed.to_string()]);
        if let Some(c) = columns {
            cmd.args(["--columns", &c.to_string()]);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("cloud.pcd")
    };
    let sweeps: Vec<PathBuf> = (1..=3).map(|s| simulate(s, None)).collect();
    let model = dir.join("cup3.toml");
    let o = Command::new(bin)
        .args(["learn", "--name", "cup3", "--out"])
        .arg(&model)
        .arg("--cloud")
        .args(&sweeps)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(text.contains("the per-pixel median of 3 sweeps"), "{text}");
    let m = Model::from_toml_str(&text, &model).unwrap();
    // The shipped cup's body: 38 mm radius, 48 mm half-height.
    let a = m.parts[0].shape.a;
    assert!((a[0] - 0.038).abs() < 0.005 && (a[2] - 0.048).abs() < 0.005, "{a:?}");
    // A sweep of another size is not the same view.
    let other = simulate(4, Some(128));
    let o = Command::new(bin)
        .args(["learn", "--name", "bad", "--out"])
        .arg(dir.join("bad.toml"))
        .arg("--cloud")
        .arg(&sweeps[0])
        .arg(&other)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("sweep 2 is 128x150, sweep 1 is 256x150"), "{err}");
    assert!(!dir.join("bad.toml").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A box seen at its corner (its moment axes are its diagonals: the start that becomes a diamond
/// when nothing bounds the hidden sides) is learned as the box, through the CLI's `--rpy`.
#[test]
fn a_carton_seen_at_its_corner_is_a_box() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_sqscan");
    let dir = std::env::temp_dir().join(format!("sqscan-learn-carton-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("carton.toml"),
        "name = \"carton\"\n[[part]]\nname = \"body\"\na = [0.035, 0.035, 0.100]\ne1 = 0.1\ne2 = 0.1\n",
    )
    .unwrap();
    let learn = |rpy: &str| {
        Command::new(bin)
            .args(["learn", "--simulate", "carton", "--rpy", rpy])
            .arg("--models-dir")
            .arg(&dir)
            .output()
            .unwrap()
    };
    // 48 degrees of yaw: the sensor, 3 degrees to the side, looks at the corner.
    let o = learn("0,0,48");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["within_tolerance"], true, "{r}");
    assert!(r["learned"]["e2"].as_f64().unwrap() < 0.3, "{r}");
    let o = learn("0,48");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--rpy") && err.contains("three finite numbers"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The everyday shapes of a table, each learned from one simulated view through the CLI: a box
/// lying flat and turned, a can lying on its side and a flat round tin come back in the right
/// family (a box's cross-section square, e2 below 0.3; a can's and a tin's round, e2 above 0.8)
/// and with every size within 10 % of the truth.
#[test]
fn a_box_a_lying_can_and_a_flat_tin_are_learned_from_one_view() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_sqscan");
    let dir = std::env::temp_dir().join(format!("sqscan-learn-everyday-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let shapes = [
        ("box", "[0.06, 0.04, 0.03]", 0.1, "0,0,30"),
        ("lying_can", "[0.035, 0.035, 0.1]", 1.0, "90,0,20"),
        ("flat_tin", "[0.09, 0.09, 0.035]", 1.0, "0,0,0"),
    ];
    for (name, a, e2, rpy) in shapes {
        std::fs::write(
            dir.join(format!("{name}.toml")),
            format!("name = \"{name}\"\n[[part]]\nname = \"body\"\na = {a}\ne1 = 0.1\ne2 = {e2}\n"),
        )
        .unwrap();
        let o = Command::new(bin)
            .args(["learn", "--simulate", name, "--rpy", rpy, "--seed", "1"])
            .arg("--models-dir")
            .arg(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let learned_e2 = r["learned"]["e2"].as_f64().unwrap();
        if e2 < 0.5 {
            assert!(learned_e2 < 0.3, "{name}: {r}");
        } else {
            assert!(learned_e2 > 0.8, "{name}: {r}");
        }
        for k in 0..3 {
            let truth = r["truth"]["a"][k].as_f64().unwrap();
            let axis = r["errors"]["axis_of"][k].as_u64().unwrap() as usize;
            let got = r["learned"]["a"][axis].as_f64().unwrap();
            assert!(
                (got - truth).abs() < 0.1 * truth,
                "{name}: axis {k}: {got} for {truth}: {r}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A spray tin (66 mm across, 190 mm tall) standing on a book 30 mm thick, simulated and learned
/// with `--label`: it rests on the book's top round its foot, and comes back its own height, not
/// the book's more (`support` in the JSON: the book's top, 30 mm over the table).
#[test]
fn a_tin_standing_on_a_book_is_learned_its_own_height() {
    use std::process::Command;
    let bin = env!("CARGO_BIN_EXE_sqscan");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("sqscan-learn-on-book-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let rig = std::fs::read_to_string(root.join("scenes/stacked/mug_on_book.toml")).unwrap();
    let rig = &rig[..rig.find("[[object]]").unwrap()];
    let scene = dir.join("tin_on_book.toml");
    std::fs::write(
        &scene,
        format!(
            "{rig}[[object]]\nname = \"book\"\nmodel = \"book\"\npose = {{ position = [0.82, 0.0, 0.0], rpy_deg = [0.0, 0.0, 20.0] }}\n\n\
             [[object]]\nname = \"tin\"\nmodel = \"spray_tin\"\npose = {{ position = [0.82, 0.0, 0.030] }}\n"
        ),
    )
    .unwrap();
    let o = Command::new(bin)
        .arg("simulate")
        .arg("--models-dir")
        .arg(root.join("models"))
        .arg(&scene)
        .arg("--out")
        .arg(dir.join("sweep"))
        .args(["--seed", "1"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The simulator labels object k (from 0) 20 + 10 k: the tin is object 3.
    let o = Command::new(bin)
        .args(["learn", "--label", "3", "--name", "tin", "--out"])
        .arg(dir.join("tin.toml"))
        .arg("--cloud")
        .arg(dir.join("sweep/cloud.pcd"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let plane: Vec<f64> = r["plane"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let support: Vec<f64> = r["support"]
        .as_array()
        .expect("a support")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    // Parallel planes: the support's offset from the table's is the book's thickness.
    assert!(
        (plane[3] - support[3] - 0.03).abs() < 0.003,
        "plane {plane:?}, support {support:?}"
    );
    let a: Vec<f64> = r["parts"][0]["a"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (got, want) in a.iter().zip([0.033, 0.033, 0.095]) {
        assert!((got - want).abs() < 0.1 * want, "a {a:?}");
    }
    let text = std::fs::read_to_string(dir.join("tin.toml")).unwrap();
    assert!(text.contains("stands on a level surface"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A cloud of the object alone (PCL's segmented milk carton, `tests/data/real/milk.pcd`) learned
/// without `--segmented`: segmentation takes the carton's largest face for the table and leaves
/// a sliver of 16 points; the error says so and names the flag, and with it the carton is
/// learned.
#[test]
fn a_segmented_cloud_learned_without_segmented_names_the_flag() {
    let dir = std::env::temp_dir().join(format!("sqscan-learn-milk-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let learn = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_sqscan"))
            .args(["learn", "--name", "milk", "--force", "--out"])
            .arg(dir.join("milk.toml"))
            .arg("--cloud")
            .arg(crate::common::real_data("milk.pcd"))
            .args(extra)
            .output()
            .unwrap()
    };
    let o = learn(&[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("of the cloud's 13704 points") && err.contains("give --segmented"),
        "{err}"
    );
    let o = learn(&["--segmented"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}
