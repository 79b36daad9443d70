//! Sweeps in the loop: the rig mock (mock PowerCube + mock sensor rendering the Fig. 3 table at
//! the PTU's angles at each exposure) on ptys in this process, the real PowerCube driver and the
//! real sensor device opened on them, and `sweep::acquire` assembling what they deliver.

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use crate::common::root;
use nalgebra::Point3;
use sqscan::geometry::PlacedSuperquadric;
use sqscan::mock::rig::{RigConfig, RigMock};
use sqscan::sim::{self, Scene};
use sqscan::sweep::{Sweep, SweepError, SweepSettings, acquire, acquire_live};
use sqscan_drivers::PanTilt;
use sqscan_drivers::PtuKind;
use sqscan_drivers::mock::Faults;
use sqscan_drivers::powercube::{PowerCubeConfig, PowerCubePtu};
use sqscan_drivers::sensor::{ProfileSensor, SensorConfig};

/// The Fig. 3 scene without sensor noise or dropouts: every return is exactly on a surface (up
/// to the 1/16 px row quantisation, about a millimetre here), so what is left is the assembly.
/// Loaded once for all tests here (loading the models takes seconds).
fn scene() -> Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(load_scene).clone()
}

fn load_scene() -> Scene {
    let mut scene = Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models")).unwrap();
    scene.rig.sensor.noise_sigma_at_1m = 0.0;
    scene.rig.sensor.dropout = 0.0;
    scene
}

fn settings(scene: &Scene) -> SweepSettings {
    SweepSettings {
        pan_rad: scene.rig.pan,
        tilt_from_rad: scene.rig.tilt_start,
        tilt_to_rad: scene.rig.tilt_end,
        speed_rad_s: scene.rig.tilt_speed,
        approach_speed_rad_s: 1.0,
        min_profiles: 100,
        ..SweepSettings::default()
    }
}

fn ptu_config() -> PowerCubeConfig {
    PowerCubeConfig {
        reply_timeout: Duration::from_millis(500),
        retries: 3,
        ..PowerCubeConfig::default()
    }
}

/// Distance from `p` to the nearest surface of the scene: the table top (within its extent),
/// the floor if any, and every object part.
fn surface_distance(scene: &Scene, parts: &[PlacedSuperquadric], p: &Point3<f64>) -> f64 {
    let mut d = f64::INFINITY;
    if let Some(t) = &scene.table
        && t.contains_xy(p.x, p.y)
    {
        d = d.min((p.z - t.height).abs());
    }
    if scene.floor {
        d = d.min(p.z.abs());
    }
    for part in parts {
        d = d.min(part.surface_distance(p).abs());
    }
    d
}

/// The sweep covers the scene's tilt range in order, and its points lie on the scene.
fn check_sweep(scene: &Scene, s: &Sweep, from: f64, to: f64, corrupt_every: usize) {
    let r = &s.report;
    let dropped = r.dropped_extrapolated
        + r.dropped_duplicate
        + r.dropped_out_of_order
        + r.dropped_bad_columns
        + r.dropped_bad_encoding;
    assert_eq!(r.kept + dropped, r.received, "{r:?}");
    assert_eq!(r.dropped_duplicate + r.dropped_out_of_order, 0, "{r:?}");
    // A frame failing its CRC is skipped by the decoder: its sequence number is missing.
    let corrupted = r.received.checked_div(corrupt_every).unwrap_or(0);
    assert!(
        r.missing_seq >= corrupted.saturating_sub(1) && r.missing_seq <= corrupted + 1,
        "{} missing, every {corrupt_every}th frame corrupted: {r:?}",
        r.missing_seq
    );
    assert_eq!(r.dropped_bad_columns + r.dropped_bad_encoding, 0, "{r:?}");
    // 2.9 s at 50 Hz.
    let nominal = (to - from).abs() / scene.rig.tilt_speed * 50.0;
    assert!(
        (s.profiles as f64) > 0.9 * nominal && (s.profiles as f64) < 1.15 * nominal,
        "{} profiles, about {nominal:.0} expected: {r:?}",
        s.profiles
    );
    assert_eq!((s.cloud.width, s.cloud.height), (s.columns, s.profiles));
    assert_eq!(s.columns, scene.rig.sensor.columns);
    let sign = (to - from).signum();
    assert!(
        s.tilt_rad.windows(2).all(|w| sign * (w[1] - w[0]) >= -1e-4),
        "tilt runs from {from} to {to}"
    );
    let (first, last) = (s.tilt_rad[0], s.tilt_rad[s.profiles - 1]);
    assert!(
        (first - from).abs() < 0.01 && (last - to).abs() < 0.01,
        "tilt {first} .. {last}"
    );
    assert!(s.stamp_s.windows(2).all(|w| w[1] > w[0]));

    // About as many returns a profile as the simulator's ideal sweep of the same scene.
    let ideal = sim::simulate(scene, 1);
    let per_profile = r.points as f64 / s.profiles as f64;
    let ideal_per_profile = ideal.finite_points() as f64 / ideal.profiles as f64;
    assert!(
        (per_profile / ideal_per_profile - 1.0).abs() < 0.1,
        "{per_profile:.1} returns a profile, the simulator has {ideal_per_profile:.1}"
    );

    // Every point on a surface (measured: median 0.2 mm, 99% 0.6 mm): a profile given the tilt
    // of 10 ms earlier or later would be off by ~1.5 mm at this range, a 40 ms slip by 6 mm.
    let parts: Vec<PlacedSuperquadric> = scene.labelled_parts().into_iter().map(|(_, p, _)| p).collect();
    let mut dist: Vec<f64> = s
        .cloud
        .points
        .iter()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .map(|p| {
            surface_distance(
                scene,
                &parts,
                &Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])),
            )
        })
        .collect();
    assert_eq!(dist.len(), r.points);
    dist.sort_by(f64::total_cmp);
    let q = |f: f64| dist[((dist.len() - 1) as f64 * f) as usize];
    let (median, p99) = (q(0.5), q(0.99));
    eprintln!(
        "{} profiles, tilt {first:.4} .. {last:.4}, surface distance median {median:.5} m, 99% {p99:.5} m: {r:?}",
        s.profiles
    );
    assert!(
        median < 0.001 && p99 < 0.002,
        "surface distance median {median}, 99% {p99}"
    );
    let far = dist.iter().filter(|&&d| d > 0.005).count();
    assert!(
        far * 1000 < dist.len(),
        "{far} of {} points more than 5 mm off",
        dist.len()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sweep_and_its_return_assemble_onto_the_scene() {
    let scene = scene();
    let cal = scene.rig.calibration();
    let cfg = RigConfig {
        ptu_kind: PtuKind::PowerCube,
        rate_hz: 50.0,
        ..RigConfig::default()
    };
    let rig = RigMock::start(Arc::new(scene.clone()), &cfg, None, None).unwrap();
    let mut ptu = PowerCubePtu::open(&rig.ptu_path, ptu_config()).await.unwrap();
    let mut sensor = ProfileSensor::open(&rig.sensor_path, SensorConfig::default()).unwrap();

    let there = settings(&scene);
    let s = acquire(&mut ptu, &mut sensor, &cal, &there).await.unwrap();
    check_sweep(&scene, &s, there.tilt_from_rad, there.tilt_to_rad, 0);

    // Back again: the same call with the tilts swapped, each position sample handed on as it
    // is read: all those the assembler used, in time order, during the move (the sweep's
    // profiles lie between the first and the last).
    let back = there.reversed();
    let mut live: Vec<(std::time::Instant, f64)> = Vec::new();
    let s = acquire_live(&mut ptu, &mut sensor, &cal, &back, |p| live.push((p.t, p.tilt_rad)))
        .await
        .unwrap();
    check_sweep(&scene, &s, back.tilt_from_rad, back.tilt_to_rad, 0);
    assert_eq!(live.len(), s.report.position_samples);
    assert!(live.windows(2).all(|w| w[0].0 < w[1].0), "samples out of time order");
    let start = s.start.expect("an assembled sweep's start");
    let last = start + std::time::Duration::from_secs_f64(*s.stamp_s.last().unwrap());
    assert!(live[0].0 <= start && live[live.len() - 1].0 >= last);
    assert!((live[0].1 - back.tilt_from_rad).abs() < 0.01 && (live[live.len() - 1].1 - back.tilt_to_rad).abs() < 0.01);
    rig.shutdown();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ptu_unplugged_mid_sweep_fails_the_sweep_and_comes_back() {
    let scene = scene();
    let cal = scene.rig.calibration();
    let dir = std::env::temp_dir().join(format!("sqscan-sweep-hil-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ptu");
    let cfg = RigConfig {
        ptu_kind: PtuKind::PowerCube,
        rate_hz: 50.0,
        // Start-up and the approach take well under 100 replies; the sweep ~300.
        ptu_faults: Faults {
            disconnect_after: Some(200),
            ..Faults::default()
        },
        ptu_replug_after: Some(Duration::from_millis(300)),
        // Line noise on the sensor meanwhile: frames lost to CRC failures show as gaps.
        sensor_faults: Faults {
            corrupt_every: 20,
            ..Faults::default()
        },
        ..RigConfig::default()
    };
    let mut rig = RigMock::start(Arc::new(scene.clone()), &cfg, Some(&link), None).unwrap();
    let mut ptu = PowerCubePtu::open(&link, ptu_config()).await.unwrap();
    let mut sensor = ProfileSensor::open(&rig.sensor_path, SensorConfig::default()).unwrap();

    let there = settings(&scene);
    let e = acquire(&mut ptu, &mut sensor, &cal, &there)
        .await
        .expect_err("the PTU was unplugged");
    assert!(matches!(e, SweepError::Ptu(_)), "{e}");
    // Mid-sweep: the unit is between the ends (the device goes on moving; read it at once).
    let (_, tilt) = rig.ptu.lock().unwrap().joint_angles(std::time::Instant::now());
    assert!(
        tilt > there.tilt_from_rad + 0.02 && tilt < there.tilt_to_rad - 0.02,
        "unplugged at tilt {tilt}"
    );
    assert!(rig.ptu_replugged.borrow().is_none(), "not back before the replug delay");

    // Back on a new pty behind the same link.
    tokio::time::timeout(Duration::from_secs(5), rig.ptu_replugged.wait_for(Option::is_some))
        .await
        .expect("replugged in time")
        .unwrap();
    let new_path = rig.ptu_replugged.borrow().clone().unwrap();
    // (The kernel may hand out the old pty number again: the path alone proves nothing.)
    assert_eq!(std::fs::read_link(&link).unwrap(), new_path);
    assert!(!rig.ptu_task.is_finished(), "the replugged PTU is being served");

    // The same link opens again and sweeps (back, from where the unit is), and it is not
    // unplugged again after another 200 replies.
    ptu.reconnect().await.unwrap();
    let at = ptu.position().await.unwrap();
    assert!(at.tilt_rad.is_finite());
    let back = there.reversed();
    let s = acquire(&mut ptu, &mut sensor, &cal, &back).await.unwrap();
    check_sweep(&scene, &s, back.tilt_from_rad, back.tilt_to_rad, 20);
    assert!(!rig.ptu_task.is_finished());
    assert!(!rig.sensor_task.is_finished(), "the sensor streamed on");
    rig.shutdown();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sensor_unplugged_mid_sweep_fails_the_sweep_and_halts_the_ptu() {
    let scene = scene();
    let cal = scene.rig.calibration();
    let cfg = RigConfig {
        ptu_kind: PtuKind::PowerCube,
        rate_hz: 50.0,
        // One second of the ~3 s sweep (the sensor only streams once started).
        sensor_faults: Faults {
            disconnect_after: Some(50),
            ..Faults::default()
        },
        ..RigConfig::default()
    };
    let rig = RigMock::start(Arc::new(scene.clone()), &cfg, None, None).unwrap();
    let mut ptu = PowerCubePtu::open(&rig.ptu_path, ptu_config()).await.unwrap();
    let mut sensor = ProfileSensor::open(&rig.sensor_path, SensorConfig::default()).unwrap();
    let there = settings(&scene);
    let e = acquire(&mut ptu, &mut sensor, &cal, &there)
        .await
        .expect_err("the sensor was unplugged");
    assert!(matches!(e, SweepError::Sensor(_)), "{e}");
    // Halted mid-sweep: the unit stays where it stopped.
    let a = ptu.position().await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let b = ptu.position().await.unwrap();
    assert!(
        a.tilt_rad > there.tilt_from_rad + 0.02 && a.tilt_rad < there.tilt_to_rad - 0.02,
        "stopped at tilt {}",
        a.tilt_rad
    );
    assert!(
        (a.tilt_rad - b.tilt_rad).abs() < 1e-3,
        "still moving: {} -> {}",
        a.tilt_rad,
        b.tilt_rad
    );
    rig.shutdown();
}
