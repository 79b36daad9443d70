//! ROS 2 over DDS (the `ros2` feature), seen by an independent DDS implementation: Eclipse
//! Cyclone DDS from PyPI (`cyclonedds`), with its own IDL definitions of the messages
//! (`tests/py/dds_sub.py`). DDS discovers by multicast, so the test runs inside a private network
//! namespace with only loopback (it says SKIPPED where none can be had). Without that Python it
//! says it skipped, unless `SQSCAN_REQUIRE_PYTHON_TOOLS` is set (as `scripts/test.sh` sets it).
#![cfg(feature = "ros2")]

use std::process::Command;
use std::time::Duration;

use serde_json::{Value, json};
use sqscan_drivers::mock::netns::in_private_network;

mod common;
use common::{Proc, python, root, sqscand, tmpdir, wait_for};

/// A Cyclone DDS subscriber sees the sweep a `find` asked for on `/sqscan/points` (organized,
/// NaN kept, in the configured frame, the same points as the PCD recording of that sweep), a
/// joint state per profile, the cup's detection as `find` answered it, and the rig's mount on
/// `/tf_static` as the scene file gives it.
#[test]
fn a_cyclone_dds_subscriber_sees_the_sweep_the_detection_and_the_mount() {
    let Some(python) = python(&["cyclonedds"]) else {
        return;
    };
    if !in_private_network("a_cyclone_dds_subscriber_sees_the_sweep_the_detection_and_the_mount") {
        return;
    }
    let dir = tmpdir("ros2");
    let scene = root().join("scenes/fig3_table.toml");
    let config = format!(
        "[sim]\nscene = {scene:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
         [server]\nframe_id = \"robot_base\"\n[record]\ndir = \"rec\"\n[ros2]\nnode = \"scanner\"\n"
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let socket = dir.join("sqscand.sock");
    let _daemon = sqscand(&dir, "sqscand", &[]);
    let out = Command::new(&python)
        .arg(root().join("tests/py/dds_sub.py"))
        .arg(&socket)
        .arg("cup")
        .arg("60")
        .output()
        .unwrap();
    let log = || std::fs::read_to_string(dir.join("sqscand.log")).unwrap_or_default();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        log()
    );
    let m: Value = serde_json::from_slice(&out.stdout).unwrap();
    for topic in ["points", "joints", "detections", "markers", "range", "tf_static"] {
        assert_eq!(m["matched"][topic], 1, "{topic} never matched: {m}\n{}", log());
    }
    let found = &m["reply"];
    assert_eq!(found["found"], true, "{found}");

    // The sweep: the recording's PCD of the same sweep, point for point where sampled.
    let json_path = dir.join("rec/sweep-00000001.json");
    wait_for("the recording", Duration::from_secs(30), || json_path.is_file());
    let pcd = sqscan::cloud::read_cloud(&dir.join("rec/sweep-00000001.pcd")).unwrap();
    let clouds = m["clouds"].as_array().unwrap();
    assert_eq!(clouds.len(), 1, "one sweep was made: {m}");
    let cloud = &clouds[0];
    assert_eq!(cloud["frame_id"], "robot_base");
    assert_eq!(cloud["height"].as_u64().unwrap() as usize, pcd.height);
    assert_eq!(cloud["width"].as_u64().unwrap() as usize, pcd.width);
    assert_eq!(cloud["is_dense"], false);
    assert_eq!(cloud["is_bigendian"], false);
    let names: Vec<&str> = cloud["fields"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert_eq!(&names[..3], ["x", "y", "z"]);
    let step = cloud["point_step"].as_u64().unwrap() as usize;
    assert_eq!(cloud["row_step"].as_u64().unwrap() as usize, step * pcd.width);
    assert_eq!(cloud["bytes"].as_u64().unwrap() as usize, step * pcd.points.len());
    let finite = pcd.points.iter().filter(|p| !p[0].is_nan()).count();
    assert_eq!(cloud["finite"].as_u64().unwrap() as usize, finite);
    assert_eq!(finite, found["points"].as_u64().unwrap() as usize, "{found}");
    assert!(
        finite < pcd.points.len(),
        "a simulated sweep has points without a return"
    );
    let samples = cloud["samples"].as_array().unwrap();
    assert!(samples.len() > 100, "{}", samples.len());
    for s in samples {
        let i = s[0].as_u64().unwrap() as usize;
        for k in 0..3 {
            assert_eq!(s[k + 1].as_f64().unwrap() as f32, pcd.points[i][k], "point {i}");
        }
    }

    // A joint state a profile, in time order, the last at the cloud's stamp.
    let joints = m["joints"].as_array().unwrap();
    let stamps: Vec<f64> = joints.iter().map(|j| j["stamp"].as_f64().unwrap()).collect();
    // Where the received stamps skip profiles: (index, seconds skipped).
    let gaps: Vec<(usize, f64)> = stamps
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] - w[0] > 0.03)
        .map(|(i, w)| (i, w[1] - w[0]))
        .collect();
    assert_eq!(
        joints.len(),
        pcd.height,
        "joint states received: first {:?}, last {:?}, gaps {gaps:?}, cloud stamp {}\n{}",
        stamps.first(),
        stamps.last(),
        cloud["stamp"],
        log()
    );
    assert_eq!(joints[0]["name"], json!(["ptu_pan", "ptu_tilt"]));
    assert!(stamps.windows(2).all(|w| w[0] <= w[1]), "{stamps:?}");
    assert!((stamps[stamps.len() - 1] - cloud["stamp"].as_f64().unwrap()).abs() < 1e-6);

    // The cup, as find answered it.
    let d = &m["detections"].as_array().unwrap()[0];
    assert_eq!(d["frame_id"], "robot_base");
    assert_eq!(d["detections"].as_array().unwrap().len(), 1, "{d}");
    let det = &d["detections"][0];
    assert_eq!(det["class_id"], "cup");
    assert_eq!(det["id"], "cup#0");
    assert!((det["score"].as_f64().unwrap() - found["confidence"].as_f64().unwrap()).abs() < 1e-5);
    for k in 0..3 {
        let want = found["pose"]["position"][k].as_f64().unwrap();
        assert!(
            (det["position"][k].as_f64().unwrap() - want).abs() < 1e-5,
            "{det} {found}"
        );
    }
    for k in 0..4 {
        let want = found["pose"]["orientation"][k].as_f64().unwrap();
        assert!(
            (det["orientation"][k].as_f64().unwrap() - want).abs() < 1e-5,
            "{det} {found}"
        );
    }

    // The range image: a value wherever the cloud has a point.
    let range = &m["ranges"][0];
    assert_eq!(range["frame_id"], "sqscan_sensor");
    assert_eq!(range["height"].as_u64().unwrap() as usize, pcd.height);
    assert_eq!(range["width"].as_u64().unwrap() as usize, pcd.width);
    assert_eq!(range["encoding"], "32FC1");
    assert_eq!(range["finite"].as_u64().unwrap() as usize, finite);

    // The markers: cleared, then the cup's two parts around the pose found, and the table.
    let markers = m["markers"][0].as_array().unwrap();
    assert_eq!(markers[0]["action"], 3);
    let parts: Vec<&Value> = markers.iter().filter(|k| k["ns"] == "cup" && k["type"] == 8).collect();
    assert_eq!(parts.len(), 2, "{markers:?}");
    for part in parts {
        assert_eq!(part["frame_id"], "robot_base");
        for p in part["points"].as_array().unwrap() {
            let d: f64 = (0..3)
                .map(|k| (p[k].as_f64().unwrap() - found["pose"]["position"][k].as_f64().unwrap()).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(d < 0.12, "{d}");
        }
    }
    let table = -found["plane"][3].as_f64().unwrap() / found["plane"][2].as_f64().unwrap();
    let plane = markers.iter().find(|k| k["ns"] == "plane").expect("the table");
    assert!((plane["z"].as_f64().unwrap() - table).abs() < 0.01, "{plane}");

    // The mount: the PTU in the base frame, the sensor on the tilt link, as the scene has them.
    let rig = sqscan::sim::Scene::from_file(&scene, &root().join("models"))
        .unwrap()
        .rig;
    let tf = m["tf_static"].as_array().unwrap();
    assert_eq!(tf.len(), 2, "{tf:?}");
    for (t, parent, child, iso) in [
        (&tf[0], "robot_base", "ptu_base_link", rig.ptu_in_base),
        (&tf[1], "ptu_tilt_link", "sqscan_sensor", rig.sensor_in_tilt),
    ] {
        assert_eq!(t["parent"], parent);
        assert_eq!(t["child"], child);
        let q = iso.rotation.coords;
        for k in 0..3 {
            assert!((t["translation"][k].as_f64().unwrap() - iso.translation.vector[k]).abs() < 1e-12);
        }
        for (k, want) in [q.x, q.y, q.z, q.w].into_iter().enumerate() {
            assert!((t["rotation"][k].as_f64().unwrap() - want).abs() < 1e-12, "{t}");
        }
    }
}

/// Under systemd's `RestrictAddressFamilies` without `AF_NETLINK`, RustDDS listed no network
/// interface and the node was never discovered, with nothing in the log. The daemon now refuses
/// to start there, before it says it is listening, and says what to add. (Netlink is refused
/// here with a seccomp filter, as systemd refuses it, through Debian's `python3-seccomp`.)
#[test]
fn a_node_that_cannot_list_the_interfaces_refuses_to_start() {
    let python = std::path::Path::new("/usr/bin/python3");
    let has_seccomp = Command::new(python)
        .args(["-c", "import seccomp"])
        .status()
        .is_ok_and(|s| s.success());
    if !has_seccomp {
        assert!(
            std::env::var_os("SQSCAN_REQUIRE_PYTHON_TOOLS").is_none(),
            "/usr/bin/python3 cannot import seccomp (Debian python3-seccomp), which scripts/test.sh installs"
        );
        eprintln!("a_node_that_cannot_list_the_interfaces_refuses_to_start: skipped: no python3-seccomp");
        return;
    }
    if !in_private_network("a_node_that_cannot_list_the_interfaces_refuses_to_start") {
        return;
    }
    let dir = tmpdir("ros2-netlink");
    let config = format!(
        "[sim]\nscene = {:?}\nrealtime = false\n[ros2]\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let log = dir.join("sqscand.log");
    let mut daemon = Proc(
        Command::new(python)
            .arg(root().join("tests/py/no_netlink.py"))
            .arg(env!("CARGO_BIN_EXE_sqscand"))
            .arg("--config")
            .arg(dir.join("sqscand.toml"))
            .arg("--socket")
            .arg(dir.join("sqscand.sock"))
            .env("SQSCAN_MODELS_DIR", root().join("models"))
            .stdout(std::process::Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let mut status = None;
    wait_for("sqscand to stop", Duration::from_secs(30), || {
        status = daemon.0.try_wait().unwrap();
        status.is_some()
    });
    let err = std::fs::read_to_string(&log).unwrap();
    assert!(!status.unwrap().success(), "{err}");
    assert!(err.contains("netlink") && err.contains("AF_NETLINK"), "{err}");
    // Refused at start-up: it never said where to ask, and left no socket behind.
    assert!(!err.contains("listening"), "{err}");
    assert!(!dir.join("sqscand.sock").exists());
}
