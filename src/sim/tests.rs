use super::*;
use crate::calibration::Calibration;
use std::path::{Path, PathBuf};

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("models")
}

/// A bare table scene with one sphere on it, the rig of the shipped scenes, and no noise.
fn sphere_scene(noise: f64, dropout: f64, columns: usize) -> Scene {
    let text = format!(
        r#"
[table]
height = 0.72
center = [0.85, 0.0]
size = [1.2, 1.6]

[rig]
ptu = {{ position = [0.0, 0.0, 1.35] }}
sensor_mount = {{ position = [0.05, 0.0, 0.08] }}
profiles = 120
tilt_start = 0.49
tilt_end = 0.84
tilt_speed = 0.12
columns = {columns}
fov_deg = 40.0
baseline = 0.15
range_min = 0.5
range_max = 1.6
noise_sigma_at_1m = {noise}
dropout = {dropout}
max_incidence_deg = 89.0

[[part]]
name = "sphere"
a = [0.06, 0.06, 0.06]
e1 = 1.0
e2 = 1.0
pose = {{ position = [0.85, 0.0, 0.0] }}
"#
    );
    Scene::from_toml_str(&text, Path::new("test.toml"), &models_dir()).unwrap()
}

/// Analytic segment-sphere test, independent of the superquadric ray marcher.
fn segment_hits_sphere(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, r: f64) -> bool {
    let d = b - a;
    let t = ((c - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
    (a + d * t - c).norm() < r
}

#[test]
fn laser_and_camera_shadows_of_a_sphere() {
    let scene = sphere_scene(0.0, 0.0, 256);
    let sweep = simulate(&scene, 1);
    let rig = &scene.rig;
    let centre = Point3::new(0.85, 0.0, 0.72 + 0.06);
    let r = 0.06;
    let (mut camera_shadow, mut laser_shadow, mut table_points, mut sphere_points) = (0, 0, 0, 0);
    let labels = match &sweep.cloud.fields[1].data {
        FieldData::U32(l) => l.clone(),
        _ => unreachable!(),
    };
    for i in 0..sweep.profiles {
        let pose = rig.sensor_in_base(rig.pan, sweep.tilt_rad[i]);
        let origin = Point3::from(pose.translation.vector);
        let camera = pose.transform_point(&Point3::new(0.0, 0.0, rig.sensor.baseline));
        for col in 0..sweep.columns {
            let k = i * sweep.columns + col;
            // Where this column's laser ray meets the table plane, ignoring the sphere.
            let dir = pose.rotation * rig.sensor.column_direction(col);
            let s = (0.72 - origin.z) / dir.z;
            let on_table = origin + dir * s;
            let laser_blocked = segment_hits_sphere(&origin, &on_table, &centre, r);
            let camera_blocked = segment_hits_sphere(&on_table, &camera, &centre, r);
            let p = sweep.cloud.points[k];
            if !laser_blocked && camera_blocked {
                camera_shadow += 1;
                assert!(p[0].is_nan(), "a table point in the camera shadow was returned");
            }
            if laser_blocked {
                // The laser stops on the sphere: never a table point behind it.
                assert_ne!(labels[k], LABEL_TABLE);
                if labels[k] == LABEL_NONE {
                    laser_shadow += 1;
                }
            }
            if labels[k] == LABEL_TABLE {
                table_points += 1;
                // Without noise, only the 1/16 px row quantisation moves a point off the plane.
                assert!((p[2] as f64 - 0.72).abs() < 0.003, "table point at z = {}", p[2]);
            } else if labels[k] >= 20 {
                sphere_points += 1;
                let d = (Point3::new(p[0] as f64, p[1] as f64, p[2] as f64) - centre).norm();
                assert!((d - r).abs() < 0.003, "sphere point {d} m from the centre");
            }
        }
    }
    assert!(
        camera_shadow > 50,
        "the scene must produce a camera shadow ({camera_shadow})"
    );
    assert!(
        table_points > 20_000 && sphere_points > 500,
        "{table_points} table, {sphere_points} sphere points"
    );
    // Every column whose laser hits the sphere returns from the sphere or nothing; the ones that
    // return nothing are grazing or self-shadowed from the camera.
    assert!(laser_shadow < sphere_points);
}

#[test]
fn same_seed_same_sweep_other_seed_other_noise() {
    let scene = sphere_scene(0.002, 0.01, 128);
    let a = simulate(&scene, 5);
    let b = simulate(&scene, 5);
    let c = simulate(&scene, 6);
    let bits = |s: &Sweep| {
        s.cloud
            .points
            .iter()
            .flat_map(|p| p.map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_ne!(bits(&a), bits(&c));
}

#[test]
fn a_simulated_sweep_reports_every_profile_kept() {
    let scene = sphere_scene(0.002, 0.01, 64);
    let s = simulate(&scene, 2);
    let r = &s.report;
    let n = scene.rig.profiles;
    assert_eq!((s.profiles, r.received, r.kept), (n, n, n));
    assert_eq!(r.points, s.finite_points());
    assert!(r.points > 0);
    assert_eq!(r.duration_s, *s.stamp_s.last().unwrap());
    assert_eq!(s.seq, (0..n as u32).collect::<Vec<_>>());
    assert_eq!(s.pan_rad, vec![scene.rig.pan; n]);
    assert_eq!(s.start, None);
    let dropped = r.dropped_extrapolated
        + r.dropped_duplicate
        + r.dropped_out_of_order
        + r.dropped_bad_columns
        + r.dropped_bad_encoding;
    assert_eq!((dropped, r.missing_seq, r.position_samples), (0, 0, 0));
}

#[test]
fn range_noise_grows_as_triangulation_does() {
    // Table only: compare each returned range with the exact range to the plane.
    let mut scene = sphere_scene(0.002, 0.0, 256);
    scene.free_parts.clear();
    let sweep = simulate(&scene, 9);
    let rig = &scene.rig;
    let mut normalised = Vec::new();
    for i in 0..sweep.profiles {
        let pose = rig.sensor_in_base(rig.pan, sweep.tilt_rad[i]);
        let origin = Point3::from(pose.translation.vector);
        for col in 0..sweep.columns {
            let r = sweep.range_m[i * sweep.columns + col];
            if !r.is_finite() {
                continue;
            }
            let dir = pose.rotation * rig.sensor.column_direction(col);
            let t = (0.72 - origin.z) / dir.z;
            let depth = t * rig.sensor.column_direction(col).x;
            // Depth noise is sigma_1m * depth^2; range = depth / cos(psi).
            let sigma = 0.002 * depth * depth / rig.sensor.column_direction(col).x;
            normalised.push((r as f64 - t) / sigma);
        }
    }
    let n = normalised.len() as f64;
    let mean = normalised.iter().sum::<f64>() / n;
    let sd = (normalised.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    assert!(mean.abs() < 0.05, "bias {mean} sigma");
    // Quantisation to 1/16 px adds a little variance on top of the Gaussian.
    assert!(sd > 0.95 && sd < 1.15, "normalised noise sd {sd}");
}

#[test]
fn sensor_rows_round_trip() {
    let s = sphere_scene(0.0, 0.0, 256).rig.sensor;
    for depth in [0.5, 0.8, 1.0, 1.3, 1.6] {
        let row = s.row_of_depth(depth);
        assert!((s.depth_of_row(row) - depth).abs() < 1e-12);
        let q = s.decode_row(s.encode_row(row)).unwrap();
        assert!((q - row).abs() <= 0.5 / 16.0 + 1e-12);
        assert!(row >= 1.0 - 1e-9 && row < s.rows as f64);
    }
    assert_eq!(s.encode_row(-3.0), 0);
    assert_eq!(s.decode_row(0), None);
}

#[test]
fn paper_scenes_load_and_have_the_papers_point_counts() {
    for (file, paper) in [("fig3_table.toml", 37_708.0), ("fig4_tools.toml", 31_101.0)] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(file);
        let scene = Scene::from_file(&path, &models_dir()).unwrap();
        let sweep = simulate(&scene, 0);
        let n = sweep.finite_points() as f64;
        eprintln!("{file}: {n} points");
        assert!((n - paper).abs() < 0.15 * paper, "{file}: {n} points, paper {paper}");
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn fig3() -> Scene {
    Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models")).unwrap()
}

/// `sim_rig.toml` is generated from the scene's rig; `SQSCAN_REGENERATE=1` rewrites it.
#[test]
fn sim_rig_file_is_the_rig_of_fig3() {
    let path = root().join("calibration/sim_rig.toml");
    let derived = fig3().rig.calibration();
    if std::env::var_os("SQSCAN_REGENERATE").is_some() {
        // Atomically: the other tests read this file in parallel.
        let tmp = path.with_extension("toml.tmp");
        std::fs::write(
            &tmp,
            derived.to_toml("The simulated rig of scenes/fig3_table.toml").unwrap(),
        )
        .unwrap();
        std::fs::rename(&tmp, &path).unwrap();
    }
    let file = Calibration::from_file(&path).unwrap();
    assert!((file.homography - derived.homography).amax() < 1e-9, "{file:?}");
    for (a, b) in [
        (file.laser_plane_in_sensor, derived.laser_plane_in_sensor),
        (file.sensor_in_tilt, derived.sensor_in_tilt),
        (file.ptu_in_base, derived.ptu_in_base),
    ] {
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
    }
    assert_eq!(
        (file.columns, file.fraction_bits),
        (derived.columns, derived.fraction_bits)
    );
    assert_eq!(
        (file.pan_axis(), file.tilt_axis()),
        (derived.pan_axis(), derived.tilt_axis())
    );
}

#[test]
fn calibrated_raw_rows_are_the_simulators_points() {
    let scene = fig3();
    let rig = &scene.rig;
    let cal = Calibration::from_file(&root().join("calibration/sim_rig.toml")).unwrap();
    let seed = 3;
    let sweep = simulate(&scene, seed);
    let mut compared = 0;
    for i in [0, 40, 75, 110, rig.profiles - 1] {
        // The raw rows `simulate` built profile i's points from.
        let tilt = sweep.tilt_rad[i];
        let pose = rig.sensor_in_base(rig.pan, tilt);
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, i as u64));
        let raw = render_profile(&scene, &pose, &mut rng);
        for (col, &value) in raw.rows.iter().enumerate() {
            let want = sweep.cloud.points[i * sweep.columns + col];
            let Some(got) = cal.point_in_base(col, value, sweep.pan_rad[i], tilt) else {
                assert!(want[0].is_nan(), "profile {i} col {col}: a point without a return");
                continue;
            };
            // The cloud stores f32: ~1e-7 m of rounding at these distances.
            let want = Point3::new(f64::from(want[0]), f64::from(want[1]), f64::from(want[2]));
            assert!((got - want).norm() < 1e-6, "profile {i} col {col}: {got} vs {want}");
            compared += 1;
        }
    }
    assert!(compared > 500, "only {compared} returns compared");
}
