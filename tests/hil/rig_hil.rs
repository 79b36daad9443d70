//! The whole rig in the loop: the rig mock (mock PowerCube + mock sensor rendering the Fig. 3
//! table) on ptys in this process, the real PTU driver and the real sensor device on the other
//! side, and the calibration turning raw profiles into base-frame points.

use std::sync::Arc;
use std::time::Duration;

use crate::common::root;
use sqscan::mock::rig::{RigConfig, RigMock};
use sqscan::sim::Scene;
use sqscan_drivers::PtuKind;
use sqscan_drivers::powercube::{PowerCubeConfig, PowerCubePtu};
use sqscan_drivers::profile::SeqEvent;
use sqscan_drivers::sensor::{ProfileSensor, SensorConfig};
use sqscan_drivers::{Goal, PanTilt};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn profiles_at_a_commanded_tilt_calibrate_onto_the_table() {
    let mut scene = Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models")).unwrap();
    // Only the table: every return on it must be on its plane. Exact rows (no noise, no
    // dropouts) leave only the 1/16 px quantisation (~1 mm at this range).
    scene.objects.clear();
    scene.free_parts.clear();
    scene.rig.sensor.noise_sigma_at_1m = 0.0;
    scene.rig.sensor.dropout = 0.0;
    let table = scene.table.clone().expect("fig3 has a table");
    let cal = scene.rig.calibration();
    let rig = RigMock::start(
        Arc::new(scene),
        &RigConfig {
            ptu_kind: PtuKind::PowerCube,
            ..RigConfig::default()
        },
        None,
        None,
    )
    .unwrap();

    let ptu_cfg = PowerCubeConfig {
        reply_timeout: Duration::from_millis(500),
        retries: 3,
        ..PowerCubeConfig::default()
    };
    let mut ptu = PowerCubePtu::open(&rig.ptu_path, ptu_cfg).await.unwrap();
    let goal = Goal {
        pan_rad: 0.05,
        tilt_rad: 0.7,
        speed_rad_s: 1.0,
    };
    let at = ptu.move_and_track(goal, None, Duration::from_secs(30)).await.unwrap();
    assert!((at.tilt_rad - 0.7).abs() < 1e-3, "{at:?}");

    let mut sensor = ProfileSensor::open(&rig.sensor_path, SensorConfig::default()).unwrap();
    sensor.start().await.unwrap();
    let mut on_table = 0;
    let mut last_stamp = None;
    for _ in 0..5 {
        let r = sensor.next_profile(Duration::from_secs(10)).await.unwrap();
        assert!(matches!(r.seq, SeqEvent::First | SeqEvent::InOrder), "{:?}", r.seq);
        assert!(
            last_stamp.is_none_or(|t| r.profile.timestamp_ns > t),
            "sensor clock runs forward"
        );
        last_stamp = Some(r.profile.timestamp_ns);
        assert_eq!(r.profile.columns(), cal.columns);
        for (col, &raw) in r.profile.rows.iter().enumerate() {
            let Some(p) = cal.point_in_base(col, raw, at.pan_rad, at.tilt_rad) else {
                continue;
            };
            if table.contains_xy(p.x, p.y) {
                assert!(
                    (p.z - table.height).abs() < 0.005,
                    "col {col}: {p} is off the table plane"
                );
                on_table += 1;
            }
        }
    }
    sensor.stop().await.unwrap();
    // At tilt 0.7 the whole fan lands on the table, about 1.1 m away.
    assert!(on_table > 5 * cal.columns / 2, "only {on_table} points on the table");
    rig.shutdown();
}
