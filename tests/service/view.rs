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

use crate::common::{Proc, ask, free_port, node_modules, python, root, rss, sqscand, tmpdir, wait_for};

/// A client that connects and subscribes sees the server's info, the three advertised channels,
/// then the sweep a `find` asked for (organized, in the configured frame, as many points as the
/// reply says), a joint state per profile, and the cup's detection as `find` answered it.
#[test]
fn a_foxglove_client_sees_the_sweep_and_the_detection() {
    let Some(python) = python(&["websockets", "mcap_ros2"]) else {
        return;
    };
    let (_daemon, dir, port) = on_demand_view("view");
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
            (
                "/sqscan/markers",
                "visualization_msgs/msg/MarkerArray",
                "cdr",
                "ros2msg"
            ),
            ("/sqscan/points", "sensor_msgs/msg/PointCloud2", "cdr", "ros2msg"),
            ("/sqscan/range", "sensor_msgs/msg/Image", "cdr", "ros2msg"),
            ("/tf", "tf2_msgs/msg/TFMessage", "cdr", "ros2msg"),
            ("/tf_static", "tf2_msgs/msg/TFMessage", "cdr", "ros2msg"),
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

    // The range image: a row a profile, a value where the cloud has a point.
    let range = &seen["range"];
    assert_eq!(range["frame"], "sqscan_sensor");
    assert_eq!(
        (range["height"].as_u64(), range["width"].as_u64()),
        (Some(150), Some(256))
    );
    assert_eq!(range["encoding"], "32FC1");
    assert_eq!(range["step"], 4 * 256);
    assert_eq!(range["bytes"], 4 * 256 * 150);
    assert_eq!(range["finite"], points["finite"], "{range}");
    assert!(
        range["min"].as_f64().unwrap() > 0.3 && range["max"].as_f64().unwrap() < 3.0,
        "{range}"
    );

    // The rig: its mount as the scene gives it, and the joints at each profile as transforms
    // that agree with the joint states.
    let rig = sqscan::sim::Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models"))
        .unwrap()
        .rig;
    let tf_static = seen["tf_static"].as_array().unwrap();
    assert_eq!(tf_static.len(), 2);
    for (t, parent, child, iso) in [
        (&tf_static[0], "robot_base", "ptu_base_link", rig.ptu_in_base),
        (&tf_static[1], "ptu_tilt_link", "sqscan_sensor", rig.sensor_in_tilt),
    ] {
        assert_eq!((t["parent"].as_str(), t["child"].as_str()), (Some(parent), Some(child)));
        for k in 0..3 {
            assert!((t["translation"][k].as_f64().unwrap() - iso.translation.vector[k]).abs() < 1e-12);
        }
    }
    assert_eq!(seen["tf"], 150);
    let last_tf = seen["last_tf"].as_array().unwrap();
    let joint = &seen["last_joint_state"];
    assert_eq!(
        (last_tf[0]["parent"].as_str(), last_tf[0]["child"].as_str()),
        (Some("ptu_base_link"), Some("ptu_pan_link"))
    );
    assert_eq!(
        (last_tf[1]["parent"].as_str(), last_tf[1]["child"].as_str()),
        (Some("ptu_pan_link"), Some("ptu_tilt_link"))
    );
    let (pan, tilt) = (
        joint["position"][0].as_f64().unwrap(),
        joint["position"][1].as_f64().unwrap(),
    );
    assert!(
        (last_tf[0]["rotation"][2].as_f64().unwrap() - (pan / 2.0).sin()).abs() < 1e-9,
        "{last_tf:?}"
    );
    assert!(
        (last_tf[1]["rotation"][1].as_f64().unwrap() - (tilt / 2.0).sin()).abs() < 1e-9,
        "{last_tf:?}"
    );
    assert!((last_tf[1]["stamp"].as_f64().unwrap() - joint["stamp"].as_f64().unwrap()).abs() < 1e-6);

    // The markers: what was drawn cleared, the cup's two parts as points on their surfaces
    // around the pose found, each its own colour, and the table under it.
    let markers = seen["markers"].as_array().unwrap();
    assert_eq!(markers[0]["action"], 3, "DELETEALL first: {:?}", markers[0]);
    let parts: Vec<&Value> = markers.iter().filter(|m| m["ns"] == "cup" && m["type"] == 8).collect();
    assert_eq!(parts.len(), 2, "{markers:?}");
    assert_ne!(parts[0]["color"], parts[1]["color"]);
    let at: Vec<f64> = (0..3).map(|k| found["pose"]["position"][k].as_f64().unwrap()).collect();
    for part in &parts {
        assert_eq!(part["frame"], "robot_base");
        let pts = part["points"].as_array().unwrap();
        assert!(pts.len() > 50, "{}", pts.len());
        for p in pts {
            let d: f64 = (0..3)
                .map(|k| (p[k].as_f64().unwrap() - at[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(d < 0.12, "a point of the cup's part {d:.3} m from its pose");
        }
    }
    let plane = markers.iter().find(|m| m["ns"] == "plane").expect("the table");
    assert_eq!(plane["type"], 1);
    let z = plane["pose"]["position"][2].as_f64().unwrap();
    let table = -found["plane"][3].as_f64().unwrap() / found["plane"][2].as_f64().unwrap();
    assert!((z - table).abs() < 0.01, "plane at {z}, the table at {table}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Four viewers subscribed to the points that never read took the daemon from 15 MB to 3.2 GB
/// in 38 s (the crate's queue holds 1024 messages a viewer, whole sweeps each): a viewer's queue
/// is now bounded by bytes (`backlog_mb`), so they lose old sweeps while the daemon's memory
/// stays flat, and the daemon goes on answering.
#[test]
fn four_viewers_that_never_read_cost_bounded_memory() {
    let Some(python) = python(&["websockets"]) else {
        return;
    };
    let dir = tmpdir("view-stall");
    let port = free_port();
    let config = format!(
        "[sim]\nscene = {:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"continuous\"\n\
         [foxglove]\nlisten = \"127.0.0.1:{port}\"\nbacklog_mb = 4\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let daemon = sqscand(&dir, "sqscand", &[]);
    wait_for("the view's port", Duration::from_secs(30), || {
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    });
    let mut stall = Proc(
        Command::new(&python)
            .arg(root().join("tests/py/foxglove_stall.py"))
            .arg(format!("ws://127.0.0.1:{port}"))
            .arg("4")
            .arg("/sqscan/points")
            .arg("60")
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join("stall.log")).unwrap())
            .spawn()
            .unwrap(),
    );
    let mut line = String::new();
    BufReader::new(stall.0.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert_eq!(
        line.trim(),
        "subscribed",
        "{}",
        std::fs::read_to_string(dir.join("stall.log")).unwrap_or_default()
    );
    let socket = dir.join("sqscand.sock");
    let sweeps = |s: &Value| s["sweeps"]["completed"].as_u64().unwrap();
    let first = sweeps(&ask(&socket, json!({"cmd":"status"})));
    // Sweeps come as fast as the simulator makes them (tens a second): within seconds the
    // unbounded queues would have held hundreds of sweeps each.
    let mut peak = 0;
    let start = std::time::Instant::now();
    while start.elapsed() < Duration::from_secs(20) {
        peak = peak.max(rss(daemon.0.id()));
        std::thread::sleep(Duration::from_millis(200));
    }
    let last = sweeps(&ask(&socket, json!({"cmd":"status"})));
    assert!(last - first >= 200, "only {} sweeps in 20 s", last - first);
    assert!(peak < 200 << 20, "peak RSS {} MB", peak >> 20);
    drop(stall);
    let found = ask(&socket, json!({"cmd":"find","object":"cup","timeout_s":60}));
    assert_eq!(found["found"], true, "{found}");
    eprintln!("peak RSS {} MB over {} sweeps", peak >> 20, last - first);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A daemon on the simulated fig. 3 table serving the view on a free loopback port, sweeping
/// only when asked: the daemon, its directory and the port.
fn on_demand_view(name: &str) -> (Proc, std::path::PathBuf, u16) {
    let dir = tmpdir(name);
    let port = free_port();
    let config = format!(
        "[sim]\nscene = {:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
         [server]\nframe_id = \"robot_base\"\n[foxglove]\nlisten = \"127.0.0.1:{port}\"\n",
        root().join("scenes/fig3_table.toml")
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let daemon = sqscand(&dir, "sqscand", &[]);
    wait_for("the view's port", Duration::from_secs(30), || {
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    });
    (daemon, dir, port)
}

/// `tests/js/ws_protocol_client.js` in `mode` against the view on `port`: the client and its
/// output, once it said it subscribed.
fn npm_client(
    modules: &std::path::Path,
    dir: &std::path::Path,
    port: u16,
    mode: &str,
) -> (Proc, BufReader<std::process::ChildStdout>) {
    let log = dir.join(format!("npm-{mode}.log"));
    let mut client = Proc(
        Command::new("node")
            .arg(root().join("tests/js/ws_protocol_client.js"))
            .arg(format!("ws://127.0.0.1:{port}"))
            .arg("60")
            .arg(mode)
            .env("NODE_PATH", modules)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
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
        std::fs::read_to_string(&log).unwrap_or_default()
    );
    (client, out)
}

/// npm's `@foxglove/ws-protocol` client (as Foxglove Studio before the SDK and Lichtblick are)
/// offers only `foxglove.websocket.v1`, the protocol's former name, and got HTTP 400 from the
/// SDK's server. It now connects on that name, sees the seven channels and gets the sweep a
/// `find` asked for and the detection.
#[test]
fn an_npm_ws_protocol_client_on_the_former_subprotocol_sees_the_sweep_and_the_detection() {
    let Some(modules) = node_modules() else {
        return;
    };
    let (_daemon, dir, port) = on_demand_view("view-npm");
    let (_client, mut out) = npm_client(&modules, &dir, port, "all");
    let found = ask(
        &dir.join("sqscand.sock"),
        json!({"cmd":"find","object":"cup","timeout_s":60}),
    );
    assert_eq!(found["found"], true, "{found}");
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let seen: Value = serde_json::from_str(&line).unwrap_or_else(|e| {
        panic!(
            "{e}: {line:?} {}",
            std::fs::read_to_string(dir.join("npm-all.log")).unwrap_or_default()
        )
    });
    assert_eq!(seen["subprotocol"], "foxglove.websocket.v1");
    assert_eq!(seen["server_name"], "sqscand");
    let topics: Vec<&str> = seen["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t[0].as_str().unwrap())
        .collect();
    assert_eq!(
        topics,
        [
            "/sqscan/detections",
            "/sqscan/joint_states",
            "/sqscan/markers",
            "/sqscan/points",
            "/sqscan/range",
            "/tf",
            "/tf_static"
        ]
    );
    assert_eq!(seen["points"]["frame"], "robot_base", "{seen}");
    assert_eq!(
        (seen["points"]["height"].as_u64(), seen["points"]["width"].as_u64()),
        (Some(150), Some(256))
    );
    assert_eq!(seen["detections"]["frame"], "robot_base", "{seen}");
    assert_eq!(seen["detections"]["count"], 1, "{seen}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The rig's mount went out on `/tf_static` with each sweep only: a viewer that subscribed
/// between sweeps could not place the sensor until the next one. It now gets the mount as it
/// subscribes, with no sweep asked for.
#[test]
fn a_viewer_subscribing_between_sweeps_gets_the_mount_at_once() {
    let Some(modules) = node_modules() else {
        return;
    };
    let (_daemon, dir, port) = on_demand_view("view-latched");
    let (_client, mut out) = npm_client(&modules, &dir, port, "tf_static");
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let seen: Value = serde_json::from_str(&line).unwrap_or_else(|e| {
        panic!(
            "{e}: {line:?} {}",
            std::fs::read_to_string(dir.join("npm-tf_static.log")).unwrap_or_default()
        )
    });
    let rig = sqscan::sim::Scene::from_file(&root().join("scenes/fig3_table.toml"), &root().join("models"))
        .unwrap()
        .rig;
    let tf = seen["tf_static"].as_array().unwrap();
    assert_eq!(tf.len(), 2, "{seen}");
    for (t, parent, child, iso) in [
        (&tf[0], "robot_base", "ptu_base_link", rig.ptu_in_base),
        (&tf[1], "ptu_tilt_link", "sqscan_sensor", rig.sensor_in_tilt),
    ] {
        assert_eq!((t["parent"].as_str(), t["child"].as_str()), (Some(parent), Some(child)));
        for k in 0..3 {
            assert!((t["translation"][k].as_f64().unwrap() - iso.translation.vector[k]).abs() < 1e-12);
        }
    }
    let status = ask(&dir.join("sqscand.sock"), json!({"cmd":"status"}));
    assert_eq!(status["sweeps"]["completed"], 0, "{status}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A client offering no subprotocol the server speaks is refused with HTTP 400, and the answer and
/// the daemon's log say what it offered and what the server speaks (the log said "handshake
/// failed" alone).
#[test]
fn a_refused_handshake_says_which_subprotocols_were_offered() {
    use std::io::{Read, Write};
    let (daemon, dir, port) = on_demand_view("view-refused");
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\
         Sec-WebSocket-Protocol: x-viewer.v3, foxglove.sdk.v9\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    let _ = s.read_to_string(&mut answer);
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    assert!(
        answer.contains("\"x-viewer.v3\"") && answer.contains("foxglove.websocket.v1"),
        "{answer}"
    );
    let refusal_logged = || {
        std::fs::read_to_string(dir.join("sqscand.log")).is_ok_and(|log| {
            log.lines()
                .any(|l| l.contains("WARN") && l.contains("handshake failed") && l.contains("x-viewer.v3"))
        })
    };
    wait_for(
        "the refusal in the daemon's log",
        Duration::from_secs(10),
        refusal_logged,
    );
    drop(daemon);
    let _ = std::fs::remove_dir_all(&dir);
}
