//! MCAP recordings (the `mcap` feature), read back by an independent reader: PyPI `mcap` and
//! `mcap-ros2-support`'s ROS 2 decoder (`tests/py/read_mcap.py`), in the Python that
//! `scripts/test.sh` prepares (`SQSCAN_PYTHON`). Without it the test says it skipped, unless
//! `SQSCAN_REQUIRE_PYTHON_TOOLS` is set (as `scripts/test.sh` sets it).
#![cfg(feature = "mcap")]

use std::process::Command;
use std::time::Duration;

use serde_json::{Value, json};

use crate::common::{ask, python, root, sqscand, tmpdir, wait_for};

/// A sweep recorded with `[record] mcap = true`: the MCAP file beside the PCD holds the cloud
/// (organized, NaN kept, the same points as the PCD), a joint state per profile, the watched
/// cup's detection as `find` answered it, and the sweep's metadata; `sqscand --replay` serves
/// the MCAP file alone and answers as the recording daemon did.
#[test]
fn a_recorded_sweep_reads_back_with_the_pypi_mcap_reader() {
    let Some(python) = python(&["mcap", "mcap_ros2"]) else {
        return;
    };
    let dir = tmpdir("mcap");
    let config = format!(
        "[sim]\nscene = {:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
         [record]\ndir = \"rec\"\nmcap = true\n[watch]\nobjects = [\"cup\"]\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let socket = dir.join("sqscand.sock");
    let _daemon = sqscand(&dir, "sqscand", &[]);
    let found = ask(&socket, json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(found["found"], true, "{found}");
    let json_path = dir.join("rec/sweep-00000001.json");
    wait_for("the recording", Duration::from_secs(30), || json_path.is_file());
    let meta: Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert_eq!(meta["mcap"], "sweep-00000001.mcap", "{meta}");

    let out = Command::new(&python)
        .arg(root().join("tests/py/read_mcap.py"))
        .arg(dir.join("rec/sweep-00000001.mcap"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(m["profile"], "ros2");
    assert_eq!(m["topics"]["/sqscan/points"]["schema"], "sensor_msgs/msg/PointCloud2");
    assert_eq!(m["topics"]["/sqscan/points"]["encoding"], "cdr");
    assert_eq!(
        m["topics"]["/sqscan/detections"]["schema"],
        "vision_msgs/msg/Detection3DArray"
    );
    assert_eq!(
        m["topics"]["/sqscan/joint_states"]["schema"],
        "sensor_msgs/msg/JointState"
    );

    // The cloud: as the PCD beside it has it, point for point, the holes kept.
    let pcd = sqscan::cloud::read_cloud(&dir.join("rec/sweep-00000001.pcd")).unwrap();
    let cloud = &m["clouds"][0];
    assert_eq!(m["clouds"].as_array().unwrap().len(), 1);
    assert_eq!(cloud["frame"], "base_link");
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
    assert!(names.contains(&"intensity"), "{names:?}");
    let step = cloud["point_step"].as_u64().unwrap() as usize;
    assert_eq!(cloud["row_step"].as_u64().unwrap() as usize, step * pcd.width);
    assert_eq!(cloud["bytes"].as_u64().unwrap() as usize, step * pcd.points.len());
    let points = cloud["points"].as_array().unwrap();
    assert_eq!(points.len(), pcd.points.len());
    let mut holes = 0;
    for (p, q) in pcd.points.iter().zip(points) {
        if p[0].is_nan() {
            assert!(q[0].is_null());
            holes += 1;
        } else {
            for k in 0..3 {
                assert_eq!(q[k].as_f64().unwrap() as f32, p[k]);
            }
        }
    }
    assert!(holes > 0, "a simulated sweep has points without a return");

    // One joint state a profile, pan and tilt, in time order, the last at the cloud's stamp.
    let joints = m["joint_states"].as_array().unwrap();
    assert_eq!(joints.len(), pcd.height);
    assert_eq!(joints[0]["names"], json!(["ptu_pan", "ptu_tilt"]));
    let stamps: Vec<f64> = joints.iter().map(|j| j["stamp"].as_f64().unwrap()).collect();
    assert!(stamps.windows(2).all(|w| w[0] <= w[1]), "{stamps:?}");
    assert!((stamps[stamps.len() - 1] - cloud["stamp"].as_f64().unwrap()).abs() < 1e-6);
    let tilt: Vec<f64> = joints.iter().map(|j| j["position"][1].as_f64().unwrap()).collect();
    assert!(tilt[tilt.len() - 1] - tilt[0] > 0.3, "the sweep tilts: {tilt:?}");

    // The watched cup, as find answered it.
    let d = &m["detections"][0];
    assert_eq!(d["frame"], "base_link");
    let det = &d["detections"][0];
    assert_eq!(d["detections"].as_array().unwrap().len(), 1, "{d}");
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
    let size: Vec<f64> = (0..3).map(|k| det["bbox_size"][k].as_f64().unwrap()).collect();
    assert!(size.iter().all(|&s| s > 0.05 && s < 0.2), "{size:?}");

    // The range image, the joints as transforms, the rig's mount, and the cup drawn.
    let range = &m["range"];
    assert_eq!(
        (range["height"].as_u64(), range["width"].as_u64()),
        (Some(pcd.height as u64), Some(pcd.width as u64))
    );
    assert_eq!(range["encoding"], "32FC1");
    assert_eq!(range["finite"].as_u64().unwrap() as usize, pcd.points.len() - holes);
    assert_eq!(m["tf"].as_array().unwrap().len(), pcd.height);
    assert_eq!(m["tf"][0][1]["child"], "ptu_tilt_link");
    let tf_static = &m["tf_static"];
    assert_eq!(tf_static.as_array().unwrap().len(), 1);
    assert_eq!(tf_static[0][0]["parent"], "base_link");
    assert_eq!(tf_static[0][0]["child"], "ptu_base_link");
    assert_eq!(tf_static[0][1]["child"], "sqscan_sensor");
    let markers = m["markers"].as_array().unwrap();
    assert_eq!(markers[0]["action"], 3);
    assert_eq!(
        markers
            .iter()
            .filter(|k| k["ns"] == "cup" && k["type"] == 8 && k["points"].as_u64() > Some(50))
            .count(),
        2,
        "{markers:?}"
    );
    assert_eq!(markers.iter().filter(|k| k["ns"] == "plane").count(), 1);

    let sweep = &m["metadata"]["sqscan.sweep"];
    assert_eq!(sweep["id"], "1");
    assert_eq!(sweep["frame"], "base_link");

    // Read back as a cloud: the PCD's points to the bit, its organization and viewpoint.
    let back = sqscan::cloud::read_cloud(&dir.join("rec/sweep-00000001.mcap")).unwrap();
    assert_eq!((back.width, back.height), (pcd.width, pcd.height));
    assert_eq!(back.viewpoint, pcd.viewpoint);
    let bits = |c: &sqscan::cloud::PointCloud| c.points.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
    assert!(bits(&back) == bits(&pcd));

    // Cut short anywhere, or with bytes flipped, the file is an error naming it, not a panic
    // (a cut after the cloud's message may still read, as MCAP is meant to be read while it is
    // being written).
    let whole = std::fs::read(dir.join("rec/sweep-00000001.mcap")).unwrap();
    let hostile = dir.join("hostile.mcap");
    for cut in [0, 8, 9, 100, whole.len() / 3, whole.len() / 2, whole.len() - 9] {
        std::fs::write(&hostile, &whole[..cut]).unwrap();
        if let Err(e) = sqscan::cloud::read_cloud(&hostile) {
            assert!(e.to_string().contains("hostile.mcap"), "{e}");
        }
    }
    let mut flipped = whole.clone();
    for i in (8..flipped.len()).step_by(997) {
        flipped[i] ^= 0xa5;
    }
    std::fs::write(&hostile, &flipped).unwrap();
    let _ = sqscan::cloud::read_cloud(&hostile);

    // Replayed from the MCAP file alone, the sweep is sweep 1 again and gets the answer the
    // recording daemon gave, to the digit.
    let replay = dir.join("replay");
    std::fs::create_dir_all(&replay).unwrap();
    std::fs::copy(dir.join("rec/sweep-00000001.mcap"), replay.join("field.mcap")).unwrap();
    std::fs::write(dir.join("replay.toml"), "").unwrap();
    let replay_args = [replay.as_os_str(), "--replay-speed".as_ref(), "0".as_ref()];
    let _replayer = sqscand(&dir, "replay", &[&["--replay".as_ref()], &replay_args[..]].concat());
    let socket = dir.join("replay.sock");
    let again = ask(&socket, json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(again["found"], true, "{again}");
    assert_eq!(again["sweep"]["id"], found["sweep"]["id"], "{again}");
    // The recording's own id, from its metadata (it was null from an MCAP file alone).
    assert_eq!(again["sweep"]["recorded"]["id"], found["sweep"]["id"], "{again}");
    assert!(
        again["sweep"]["recorded"]["file"]
            .as_str()
            .unwrap()
            .ends_with("field.mcap"),
        "{again}"
    );
    assert_eq!(again["pose"], found["pose"], "{again} {found}");
    assert_eq!(again["confidence"], found["confidence"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A recording directory is a rosbag2 bag with MCAP storage: PyPI `rosbags` opens it, lists
/// each topic with the QoS it was offered at (`/tf_static` transient local), reads the clouds and
/// the detections in time order from every file the directory keeps (pruned to the newest two
/// of three), and finds in it everything it finds in a bag its own writer makes of the same
/// messages. In file order too, every MCAP file's messages are in log-time order (the
/// transforms of each profile once came 2.9 s after all the joint states).
#[test]
fn a_recording_directory_opens_as_a_rosbag2_bag() {
    let Some(python) = python(&["mcap", "rosbags"]) else {
        return;
    };
    // At the rig's pace: the sweeps follow each other in time, as a rig's do (a simulator that
    // does not keep the pace stamps each sweep as just made, overlapping the one before).
    let dir = tmpdir("bag");
    let config = format!(
        "[sim]\nscene = {:?}\nseed = 3\nrealtime = true\n[acquisition]\nmode = \"on_demand\"\n\
         [record]\ndir = \"rec\"\nmcap = true\nkeep = 2\n[watch]\nobjects = [\"cup\"]\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let socket = dir.join("sqscand.sock");
    let _daemon = sqscand(&dir, "sqscand", &[]);
    for _ in 0..3 {
        let scan = ask(&socket, json!({"cmd":"scan","timeout_s":60}));
        assert!(scan["sweep"]["id"].is_u64(), "{scan}");
    }
    let rec = dir.join("rec");
    let metadata = rec.join("metadata.yaml");
    wait_for("the third sweep in the bag", Duration::from_secs(30), || {
        std::fs::read_to_string(&metadata).is_ok_and(|m| m.contains("sweep-00000003.mcap"))
    });
    let yaml = std::fs::read_to_string(&metadata).unwrap();
    assert!(
        yaml.contains("  version: 5\n") && !yaml.contains("sweep-00000001.mcap"),
        "{yaml}"
    );

    let out = Command::new(&python)
        .arg(root().join("tests/py/read_bag.py"))
        .arg(&rec)
        .arg(dir.join("rosbags-bag"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(m["differences"], json!([]), "{m}");
    let topics = &m["bag"]["topics"];
    for (topic, ty) in [
        ("/sqscan/points", "sensor_msgs/msg/PointCloud2"),
        ("/sqscan/joint_states", "sensor_msgs/msg/JointState"),
        ("/sqscan/detections", "vision_msgs/msg/Detection3DArray"),
        ("/sqscan/markers", "visualization_msgs/msg/MarkerArray"),
        ("/sqscan/range", "sensor_msgs/msg/Image"),
        ("/tf", "tf2_msgs/msg/TFMessage"),
        ("/tf_static", "tf2_msgs/msg/TFMessage"),
    ] {
        assert_eq!(topics[topic]["type"], ty, "{topic}: {topics}");
        assert_eq!(topics[topic]["qos"][0]["reliability"], "reliable", "{topic}: {topics}");
    }
    assert_eq!(
        topics["/tf_static"]["qos"][0]["durability"], "transient_local",
        "{topics}"
    );
    assert_eq!(topics["/tf_static"]["count"], 2);
    assert_eq!(topics["/sqscan/points"]["qos"][0]["durability"], "volatile");
    assert_eq!(topics["/sqscan/points"]["qos"][0]["depth"], 5);
    assert_eq!(topics["/sqscan/points"]["count"], 2);
    assert_eq!(m["in_time_order"], true);
    let files = m["files_in_log_time_order"].as_object().unwrap();
    assert_eq!(files.len(), 2, "{files:?}");
    assert!(files.values().all(|v| v == true), "{files:?}");

    // The clouds and the cup's detections, decoded, in time order, one a sweep.
    let clouds = m["clouds"].as_array().unwrap();
    assert_eq!(clouds.len(), 2);
    for c in clouds {
        assert_eq!(c["frame"], "base_link");
        assert_eq!(c["t"], c["stamp"], "log time is the stamp");
    }
    assert!(clouds[0]["t"].as_u64() < clouds[1]["t"].as_u64());
    let found = m["detections"].as_array().unwrap();
    assert_eq!(found.len(), 2, "{found:?}");
    for d in found {
        assert_eq!(d["found"][0]["class"], "cup", "{d}");
    }
}
