//! The live view (the `foxglove` feature), seen by an independent client: a Foxglove WebSocket
//! client written from the protocol's description with PyPI `websockets`
//! (`tests/py/foxglove_client.py`), which decodes the messages with `mcap-ros2-support`'s ROS 2
//! decoder. Without that Python the test says it skipped, unless `SQSCAN_REQUIRE_PYTHON_TOOLS`
//! is set (as `scripts/test.sh` sets it).
#![cfg(feature = "foxglove")]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use serde_json::{Value, json};

mod common;
use common::{Proc, ask, free_port, python, root, sqscand, tmpdir, wait_for};

/// A client that connects and subscribes sees the server's info, the three advertised channels,
/// then the sweep a `find` asked for (organized, in the configured frame, as many points as the
/// reply says), a joint state per profile, and the cup's detection as `find` answered it.
#[test]
fn a_foxglove_client_sees_the_sweep_and_the_detection() {
    let Some(python) = python(&["websockets", "mcap_ros2"]) else {
        return;
    };
    let dir = tmpdir("view");
    let port = free_port();
    let config = format!(
        "[sim]\nscene = {:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
         [server]\nframe_id = \"robot_base\"\n[foxglove]\nlisten = \"127.0.0.1:{port}\"\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let _daemon = sqscand(&dir, "sqscand", &[]);
    wait_for("the view's port", Duration::from_secs(30), || {
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    });
    let mut client = Proc(
        Command::new(&python)
            .arg(root().join("tests/py/foxglove_client.py"))
            .arg(format!("ws://127.0.0.1:{port}"))
            .arg("60")
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join("client.log")).unwrap())
            .spawn()
            .unwrap(),
    );
    let mut out = BufReader::new(client.0.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert_eq!(
        line.trim(),
        "subscribed",
        "{}",
        std::fs::read_to_string(dir.join("client.log")).unwrap_or_default()
    );
    let found = ask(
        &dir.join("sqscand.sock"),
        json!({"cmd":"find","object":"cup","timeout_s":60}),
    );
    assert_eq!(found["found"], true, "{found}");
    line.clear();
    out.read_line(&mut line).unwrap();
    let seen: Value = serde_json::from_str(&line).unwrap_or_else(|e| {
        panic!(
            "{e}: {line:?} {}",
            std::fs::read_to_string(dir.join("client.log")).unwrap_or_default()
        )
    });

    assert_eq!(seen["subprotocol"], "foxglove.sdk.v1");
    assert_eq!(seen["server_info"]["name"], "sqscand");
    let topics: Vec<(&str, &str, &str, &str)> = seen["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["topic"].as_str().unwrap(),
                c["schemaName"].as_str().unwrap(),
                c["encoding"].as_str().unwrap(),
                c["schemaEncoding"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        topics,
        [
            (
                "/sqscan/detections",
                "vision_msgs/msg/Detection3DArray",
                "cdr",
                "ros2msg"
            ),
            ("/sqscan/joint_states", "sensor_msgs/msg/JointState", "cdr", "ros2msg"),
            ("/sqscan/points", "sensor_msgs/msg/PointCloud2", "cdr", "ros2msg"),
        ]
    );
    let points = &seen["points"];
    assert_eq!(points["frame"], "robot_base");
    assert_eq!(points["height"], 150);
    assert_eq!(points["width"], 256);
    assert_eq!(points["is_dense"], false);
    assert_eq!(points["finite"], found["sweep"]["points"], "{points}");
    assert_eq!(seen["joint_states"], 150);
    let cup = &seen["detections"][0][0];
    assert_eq!(cup["class_id"], "cup", "{seen}");
    assert!((cup["score"].as_f64().unwrap() - found["confidence"].as_f64().unwrap()).abs() < 1e-5);
    for k in 0..3 {
        let want = found["pose"]["position"][k].as_f64().unwrap();
        assert!(
            (cup["position"][k].as_f64().unwrap() - want).abs() < 1e-5,
            "{cup} {found}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
