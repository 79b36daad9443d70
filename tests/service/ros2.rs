//! ROS 2 over DDS (the `ros2` feature), seen by an independent DDS implementation: Eclipse
//! Cyclone DDS from PyPI (`cyclonedds`), with its own IDL definitions of the messages
//! (`tests/py/dds_sub.py`). DDS discovers by multicast, so the test runs inside a private network
//! namespace with only loopback (it says SKIPPED where none can be had). Without that Python it
//! says it skipped, unless `SQSCAN_REQUIRE_PYTHON_TOOLS` is set (as `scripts/test.sh` sets it).
//!
//! Over 600 lines: every test shares the namespace, the Cyclone subscriber and the daemon
//! harness at the top, and the hostile-peer tests need all three.
#![cfg(feature = "ros2")]

use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use sqscan_drivers::mock::netns::in_private_network;

use crate::common::{Proc, python, root, sqscand, tmpdir, wait_for};

/// A Cyclone DDS subscriber sees the sweep a `find` asked for on `/sqscan/points` (organized,
/// NaN kept, in the configured frame, the same points as the PCD recording of that sweep), a
/// joint state per profile, the cup's detection as `find` answered it, and the rig's mount on
/// `/tf_static` as the scene file gives it.
#[test]
fn a_cyclone_dds_subscriber_sees_the_sweep_the_detection_and_the_mount() {
    let Some(python) = python(&["cyclonedds"]) else {
        return;
    };
    if !in_private_network("ros2::a_cyclone_dds_subscriber_sees_the_sweep_the_detection_and_the_mount") {
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
    let mut daemon = sqscand(&dir, "sqscand", &[]);
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
    for topic in ["points", "joints", "detections", "markers", "range", "tf_static", "tf"] {
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
    // The joint states go out as the sweep is made, the cloud once it is: each takes its stamp
    // from the wall clock then, a few microseconds apart.
    assert!((stamps[stamps.len() - 1] - cloud["stamp"].as_f64().unwrap()).abs() < 1e-3);

    // /tf: the pan and tilt joints as transforms at each profile, as the joint states have them:
    // with `/tf_static`, the sensor's frame reaches the base frame at every profile's time with
    // no robot_state_publisher.
    let tf = m["tf"].as_array().unwrap();
    assert_eq!(tf.len(), pcd.height, "/tf messages received\n{}", log());
    for (t, j) in tf.iter().zip(joints) {
        let (pan, tilt) = (j["position"][0].as_f64().unwrap(), j["position"][1].as_f64().unwrap());
        assert_eq!(
            (t[0]["parent"].as_str(), t[0]["child"].as_str()),
            (Some("ptu_base_link"), Some("ptu_pan_link"))
        );
        assert_eq!(
            (t[1]["parent"].as_str(), t[1]["child"].as_str()),
            (Some("ptu_pan_link"), Some("ptu_tilt_link"))
        );
        for k in 0..2 {
            assert!(
                (t[k]["stamp"].as_f64().unwrap() - j["stamp"].as_f64().unwrap()).abs() < 1e-6,
                "{t} {j}"
            );
        }
        assert!(
            (t[0]["rotation"][2].as_f64().unwrap() - (pan / 2.0).sin()).abs() < 1e-9,
            "{t} {j}"
        );
        assert!(
            (t[1]["rotation"][1].as_f64().unwrap() - (tilt / 2.0).sin()).abs() < 1e-9,
            "{t} {j}"
        );
    }

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

    // A stop, as systemd stops it: nothing at error level from start to end (RustDDS said
    // "leave_multicast_group ... No such device" twice at every stop).
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(daemon.0.id() as i32, libc::SIGTERM) }, 0);
    let t = Instant::now();
    while daemon.0.try_wait().unwrap().is_none() {
        assert!(
            t.elapsed() < Duration::from_secs(10),
            "still running 10 s after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let errors: Vec<String> = log()
        .lines()
        .filter(|l| l.contains("ERROR"))
        .map(String::from)
        .collect();
    assert!(errors.is_empty(), "error lines in a normal start and stop: {errors:#?}");
}

/// On the mock rig (PowerCube and SQPF sensor on ptys, at their real pace), a subscriber at ROS 2's
/// default QoS (reliable, keep last 10) gets every joint state of three sweeps: each of the PTU's
/// position samples as the driver reads it, so that `/tf` carries the joints through every
/// profile's time. Sent as one burst after each sweep, a default reader kept 84 and 111 of 150.
#[test]
fn a_default_qos_reader_gets_every_joint_state_of_three_sweeps_on_the_mock_rig() {
    let Some(python) = python(&["cyclonedds"]) else {
        return;
    };
    if !in_private_network("ros2::a_default_qos_reader_gets_every_joint_state_of_three_sweeps_on_the_mock_rig") {
        return;
    }
    let dir = tmpdir("ros2-paced");
    let (_rig, ptu, sensor) = crate::common::mock_rig(&dir, "powercube", &[]);
    let config = format!(
        "{}[acquisition]\nmode = \"on_demand\"\n[server]\nframe_id = \"base_link\"\n[ros2]\nnode = \"scanner\"\n",
        crate::common::rig_config(&ptu, &sensor, "powercube", "sim_rig.toml", 0.84)
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let _daemon = sqscand(&dir, "sqscand", &[]);
    let out = Command::new(&python)
        .arg(root().join("tests/py/dds_sub.py"))
        .arg("--paced")
        .arg(dir.join("sqscand.sock"))
        .arg("3")
        .arg("90")
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
    let scans = m["scans"].as_array().unwrap();
    assert_eq!(scans.len(), 3, "{m}\n{}", log());
    let samples: u64 = scans
        .iter()
        .map(|s| s["sweep"]["report"]["position_samples"].as_u64().expect("a sweep"))
        .sum();
    let joints = m["joints"].as_array().unwrap();
    let stamps: Vec<f64> = joints.iter().map(|j| j["stamp"].as_f64().unwrap()).collect();
    let gaps: Vec<f64> = stamps.windows(2).map(|w| w[1] - w[0]).collect();
    assert_eq!(
        joints.len() as u64,
        samples,
        "joint states received of the three sweeps' position samples; gaps over 0.1 s: {:?}\n{}",
        gaps.iter().filter(|g| **g > 0.1).collect::<Vec<_>>(),
        log()
    );
    assert!(
        gaps.iter().all(|g| *g > 0.0),
        "joint states out of time order: {stamps:?}"
    );

    // /tf: the same samples as transforms.
    let tf = m["tf"].as_array().unwrap();
    assert_eq!(tf.len(), joints.len(), "/tf messages received\n{}", log());
    for (t, j) in tf.iter().zip(joints) {
        let tilt = j["position"][1].as_f64().unwrap();
        assert_eq!(t[1]["child"], "ptu_tilt_link");
        assert!(
            (t[1]["stamp"].as_f64().unwrap() - j["stamp"].as_f64().unwrap()).abs() < 1e-9,
            "{t} {j}"
        );
        assert!(
            (t[1]["rotation"][1].as_f64().unwrap() - (tilt / 2.0).sin()).abs() < 1e-9,
            "{t} {j}"
        );
    }

    // The chain from the base frame to the sensor: /tf_static's two links around /tf's two.
    let links: Vec<(&str, &str)> = m["tf_static"]
        .as_array()
        .unwrap()
        .iter()
        .chain(tf[0].as_array().unwrap())
        .map(|t| (t["parent"].as_str().unwrap(), t["child"].as_str().unwrap()))
        .collect();
    let mut frame = "base_link";
    for _ in 0..4 {
        frame = links
            .iter()
            .find(|(parent, _)| *parent == frame)
            .unwrap_or_else(|| panic!("no transform from {frame}: {links:?}"))
            .1;
    }
    assert_eq!(frame, "sqscan_sensor", "{links:?}");

    // Every profile's time lies between two samples at most 0.1 s apart: the tilt link, and
    // with /tf_static the sensor, reaches the base frame at each profile's time; at the first
    // and the last profile the interpolated tilt is the sweep's start and end.
    let clouds = m["clouds"].as_array().unwrap();
    assert_eq!(clouds.len(), 3, "clouds: {clouds:?}");
    let tilt_at = |t: f64| -> Option<f64> {
        let i = stamps.partition_point(|s| *s <= t);
        if i == 0 || i == stamps.len() {
            return None;
        }
        let (a, b) = (stamps[i - 1], stamps[i]);
        assert!(b - a < 0.1, "no joint state between {a} and {b} (profile at {t})");
        let ta = joints[i - 1]["position"][1].as_f64().unwrap();
        let tb = joints[i]["position"][1].as_f64().unwrap();
        Some(ta + (t - a) / (b - a) * (tb - ta))
    };
    for (cloud, scan) in clouds.iter().zip(scans) {
        let last = cloud["stamp"].as_f64().unwrap();
        let first = last - scan["sweep"]["report"]["duration_s"].as_f64().unwrap();
        let start = tilt_at(first).unwrap_or_else(|| panic!("no joint states around {first}: {stamps:?}"));
        let end = tilt_at(last).unwrap_or_else(|| panic!("no joint states around {last}: {stamps:?}"));
        let within: Vec<f64> = stamps.iter().copied().filter(|s| *s >= first && *s <= last).collect();
        assert!(
            within.windows(2).all(|w| w[1] - w[0] < 0.1),
            "a gap in the joint states: {within:?}"
        );
        // Back and forth: every other sweep runs from 0.84 rad back to 0.49.
        let (low, high) = (start.min(end), start.max(end));
        assert!(
            (low - 0.49).abs() < 0.03 && (high - 0.84).abs() < 0.03,
            "tilt {start} .. {end}"
        );
    }
    let errors: Vec<String> = log()
        .lines()
        .filter(|l| l.contains("ERROR"))
        .map(String::from)
        .collect();
    assert!(errors.is_empty(), "{errors:#?}");
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
    if !in_private_network("ros2::a_node_that_cannot_list_the_interfaces_refuses_to_start") {
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

/// The DDS discovery ports (domain 0, 7400 to 7419) the daemon has bound, from its network
/// namespace's UDP socket table (in the private namespace, only the daemon has sockets there).
fn dds_ports(pid: u32) -> Vec<u16> {
    let mut ports = Vec::new();
    for table in ["udp", "udp6"] {
        let text = std::fs::read_to_string(format!("/proc/{pid}/net/{table}")).unwrap_or_default();
        for line in text.lines().skip(1) {
            let Some(local) = line.split_whitespace().nth(1) else {
                continue;
            };
            let Some(port) = local.rsplit(':').next().and_then(|p| u16::from_str_radix(p, 16).ok()) else {
                continue;
            };
            if (7400..7420).contains(&port) && !ports.contains(&port) {
                ports.push(port);
            }
        }
    }
    ports.sort();
    ports
}

/// The resident memory of a process (kB, `VmRSS`), or None once it has gone.
fn rss_kb(pid: u32) -> Option<u64> {
    crate::common::try_rss(pid).map(|b| b >> 10)
}

/// A daemon with the ROS 2 node on the simulator (sweeps on demand), in the private network
/// namespace, for a flood of hostile datagrams: returned once it has bound `min_ports` of the
/// DDS ports.
struct FloodTarget {
    dir: std::path::PathBuf,
    socket: std::path::PathBuf,
    daemon: Proc,
    pid: u32,
    ports: Vec<u16>,
}

impl FloodTarget {
    fn start(name: &str, min_ports: usize) -> FloodTarget {
        let dir = tmpdir(name);
        let scene = root().join("scenes/fig3_table.toml");
        let config = format!(
            "[sim]\nscene = {scene:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
             [ros2]\nnode = \"scanner\"\n"
        );
        std::fs::write(dir.join("sqscand.toml"), config).unwrap();
        let socket = dir.join("sqscand.sock");
        let daemon = sqscand(&dir, "sqscand", &[]);
        let pid = daemon.0.id();
        let mut ports = Vec::new();
        wait_for(
            &format!("{min_ports} DDS ports of the daemon"),
            Duration::from_secs(30),
            || {
                ports = dds_ports(pid);
                ports.len() >= min_ports
            },
        );
        FloodTarget {
            dir,
            socket,
            daemon,
            pid,
            ports,
        }
    }
}

/// The largest resident memory (kB) of `pid` over `watch`, sampled every 20 ms: what the daemon
/// does with a flood it was sent, for a while after.
fn peak_rss_kb(pid: u32, watch: Duration) -> u64 {
    let (t, mut peak) = (Instant::now(), 0);
    while t.elapsed() < watch {
        peak = peak.max(rss_kb(pid).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(20));
    }
    peak
}

/// A Cyclone DDS subscriber started after a flood (waiting at most `wait_s`) matches every
/// topic and gets the sweep and the detection a `find` asks for; what it saw (`dds_sub.py`'s JSON).
fn subscriber_gets_a_sweep(
    python: &std::path::Path,
    socket: &std::path::Path,
    wait_s: u32,
    log: &dyn Fn() -> String,
) -> Value {
    let out = Command::new(python)
        .arg(root().join("tests/py/dds_sub.py"))
        .arg(socket)
        .arg("cup")
        .arg(wait_s.to_string())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        log()
    );
    let m: Value = serde_json::from_slice(&out.stdout).unwrap();
    for topic in ["points", "joints", "detections", "markers", "range", "tf_static", "tf"] {
        assert_eq!(m["matched"][topic], 1, "{topic} never matched: {m}\n{}", log());
    }
    assert_eq!(m["reply"]["found"], true, "{}", m["reply"]);
    assert_eq!(m["clouds"].as_array().unwrap().len(), 1, "a sweep after the flood: {m}");
    m
}

/// An RTPS message of one DATA_FRAG submessage (RTPS 2.4, little endian) from the participant
/// `prefix`: the first 1024-byte fragment of a sample from `writer` to `reader` (builtin entity
/// ids) that declares itself 0xFFFFFFFF bytes long.
fn data_frag_declaring_4_gib(prefix: [u8; 12], reader: [u8; 4], writer: [u8; 4], sn: u32) -> Vec<u8> {
    const FRAGMENT: u16 = 1024;
    let mut m = Vec::with_capacity(20 + 4 + 32 + FRAGMENT as usize);
    m.extend_from_slice(b"RTPS");
    m.extend_from_slice(&[2, 4]); // protocol version
    m.extend_from_slice(&[0x01, 0x99]); // a vendor id no one has
    m.extend_from_slice(&prefix);
    m.push(0x16); // DATA_FRAG
    m.push(0x01); // little endian
    m.extend_from_slice(&(4 + 28 + FRAGMENT).to_le_bytes()); // octetsToNextHeader
    m.extend_from_slice(&0u16.to_le_bytes()); // extraFlags
    m.extend_from_slice(&28u16.to_le_bytes()); // octetsToInlineQos: to the end of sampleSize
    m.extend_from_slice(&reader);
    m.extend_from_slice(&writer);
    m.extend_from_slice(&0i32.to_le_bytes()); // writerSN high
    m.extend_from_slice(&sn.to_le_bytes()); // writerSN low
    m.extend_from_slice(&1u32.to_le_bytes()); // fragmentStartingNum
    m.extend_from_slice(&1u16.to_le_bytes()); // fragmentsInSubmessage
    m.extend_from_slice(&FRAGMENT.to_le_bytes()); // fragmentSize
    m.extend_from_slice(&u32::MAX.to_le_bytes()); // sampleSize: 4 GiB
    m.extend_from_slice(&[0x00, 0x03, 0x00, 0x00]); // PL_CDR_LE, the start of the sample
    m.resize(m.len() + FRAGMENT as usize - 4, 0xA5);
    m
}

/// RustDDS allocated a reassembly buffer of the size a DATA_FRAG declares, so a few hundred
/// datagrams on the discovery ports, from anyone, each declaring a 4 GiB sample, took the
/// daemon's memory to gigabytes in seconds and then aborted it ("memory allocation of
/// 4294967295 bytes failed"), and each datagram logged errors. The patched RustDDS refuses a
/// sample larger than `[ros2] max_fragmented_sample` and holds at most a fixed budget in all
/// incomplete reassemblies; the flood leaves the daemon alive and small, its log short, and a
/// Cyclone DDS subscriber started afterwards still discovers it and gets a sweep.
#[test]
fn a_data_frag_flood_declaring_4_gib_samples_costs_bounded_memory() {
    let Some(python) = python(&["cyclonedds"]) else {
        return;
    };
    if !in_private_network("ros2::a_data_frag_flood_declaring_4_gib_samples_costs_bounded_memory") {
        return;
    }
    let FloodTarget {
        dir,
        socket,
        mut daemon,
        pid,
        ports,
    } = FloodTarget::start("ros2-datafrag", 2);
    let log = || std::fs::read_to_string(dir.join("sqscand.log")).unwrap_or_default();
    let before = rss_kb(pid).unwrap();

    // 300 datagrams to each port, from 30 participants that do not exist, each to one of the
    // builtin readers (SPDP, SEDP publications and subscriptions, participant messages), each
    // a new sample of its writer.
    const BUILTIN: [([u8; 4], [u8; 4]); 4] = [
        ([0x00, 0x01, 0x00, 0xc7], [0x00, 0x01, 0x00, 0xc2]),
        ([0x00, 0x00, 0x03, 0xc7], [0x00, 0x00, 0x03, 0xc2]),
        ([0x00, 0x00, 0x04, 0xc7], [0x00, 0x00, 0x04, 0xc2]),
        ([0x00, 0x02, 0x00, 0xc7], [0x00, 0x02, 0x00, 0xc2]),
    ];
    let out = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut peak = before;
    let t0 = Instant::now();
    let mut sent = 0;
    for i in 0..300u32 {
        let mut prefix = [0x5a; 12];
        prefix[8..].copy_from_slice(&(i % 30).to_be_bytes());
        let (reader, writer) = BUILTIN[i as usize % BUILTIN.len()];
        let datagram = data_frag_declaring_4_gib(prefix, reader, writer, 1 + i);
        for &port in &ports {
            if out.send_to(&datagram, ("127.0.0.1", port)).is_ok() {
                sent += 1;
            }
        }
        if i % 10 == 9 {
            // Paced, so that the socket buffers keep them (a flood that is dropped tests
            // nothing), and watched as it goes.
            std::thread::sleep(Duration::from_millis(5));
            peak = peak.max(rss_kb(pid).unwrap_or(0));
        }
    }
    let flood = t0.elapsed();
    // What the daemon does with what it was sent, for a few seconds more.
    peak = peak.max(peak_rss_kb(pid, Duration::from_secs(3)));
    let status = daemon.0.try_wait().unwrap();
    eprintln!(
        "{sent} DATA_FRAG datagrams to ports {ports:?} in {flood:?}: VmRSS {before} kB before, \
         peak {peak} kB, exit {status:?}"
    );
    assert!(status.is_none(), "the daemon died of the flood: {status:?}\n{}", log());
    // The daemon with the node runs in tens of megabytes (in a test build); an allocation of
    // a declared sample would take gigabytes. The bound is wide: the reassembly budget (16
    // MiB) and what the daemon does besides.
    assert!(
        peak < before + 256 * 1024,
        "VmRSS went from {before} kB to {peak} kB under the flood"
    );
    // RustDDS's complaints about the flood are rate-limited: a few lines, not one a datagram.
    let lines = log().lines().count();
    assert!(lines < 100, "{lines} lines of log:\n{}", log());

    // Discovery and delivery still work once the flood stops.
    subscriber_gets_a_sweep(&python, &socket, 60, &log);
    assert!(daemon.0.try_wait().unwrap().is_none(), "{}", log());
}

/// A seeded pseudo-random source (splitmix64): the same flood every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }

    fn entity(&mut self) -> [u8; 4] {
        // The builtin endpoints, or one of the first user entities of any kind (where the
        // daemon's own readers and writers are), or anything.
        const BUILTIN: [[u8; 4]; 9] = [
            [0x00, 0x01, 0x00, 0xc2],
            [0x00, 0x01, 0x00, 0xc7],
            [0x00, 0x00, 0x03, 0xc2],
            [0x00, 0x00, 0x03, 0xc7],
            [0x00, 0x00, 0x04, 0xc2],
            [0x00, 0x00, 0x04, 0xc7],
            [0x00, 0x02, 0x00, 0xc2],
            [0x00, 0x02, 0x00, 0xc7],
            [0x00, 0x00, 0x00, 0x00],
        ];
        const KINDS: [u8; 6] = [0x02, 0x03, 0x04, 0x07, 0xc2, 0xc7];
        match self.below(3) {
            0 => BUILTIN[self.below(BUILTIN.len() as u64) as usize],
            1 => [
                0,
                0,
                self.below(32) as u8,
                KINDS[self.below(KINDS.len() as u64) as usize],
            ],
            _ => (self.next() as u32).to_be_bytes(),
        }
    }

    /// A sequence number: small, near the top, negative or anything.
    fn seq(&mut self) -> [u8; 8] {
        let (high, low): (i32, u32) = match self.below(4) {
            0 => (0, self.below(64) as u32),
            1 => (i32::MAX, u32::MAX - self.below(4) as u32),
            2 => (-1 - self.below(4) as i32, self.next() as u32),
            _ => (self.next() as i32, self.next() as u32),
        };
        let mut b = [0; 8];
        b[..4].copy_from_slice(&high.to_le_bytes());
        b[4..].copy_from_slice(&low.to_le_bytes());
        b
    }
}

/// A made-up participant's GUID prefix (number `n` of the flood's).
fn phantom(n: u64) -> [u8; 12] {
    let mut p = [0xfa, 0x4e, 0x7a, 0x5d, 0, 0, 0, 0, 0, 0, 0, 0];
    p[4..].copy_from_slice(&n.to_be_bytes());
    p
}

fn rtps_header(prefix: &[u8; 12]) -> Vec<u8> {
    let mut m = Vec::with_capacity(256);
    m.extend_from_slice(b"RTPS");
    m.extend_from_slice(&[2, 4, 0x01, 0x99]);
    m.extend_from_slice(prefix);
    m
}

/// A submessage (little endian) of `id`, `flags` (E added) and `body`.
fn submessage(m: &mut Vec<u8>, id: u8, flags: u8, body: &[u8]) {
    m.push(id);
    m.push(flags | 0x01);
    m.extend_from_slice(&(body.len() as u16).to_le_bytes());
    m.extend_from_slice(body);
}

/// One parameter of a parameter list, padded to 4 bytes.
fn param(pl: &mut Vec<u8>, pid: u16, value: &[u8]) {
    let padded = value.len().div_ceil(4) * 4;
    pl.extend_from_slice(&pid.to_le_bytes());
    pl.extend_from_slice(&(padded as u16).to_le_bytes());
    pl.extend_from_slice(value);
    pl.resize(pl.len() + padded - value.len(), 0);
}

fn udpv4_locator(port: u32) -> Vec<u8> {
    let mut l = Vec::with_capacity(24);
    l.extend_from_slice(&1i32.to_le_bytes());
    l.extend_from_slice(&port.to_le_bytes());
    l.extend_from_slice(&[0; 12]);
    l.extend_from_slice(&[127, 0, 0, 1]);
    l
}

fn cdr_string(s: &str) -> Vec<u8> {
    let mut v = ((s.len() + 1) as u32).to_le_bytes().to_vec();
    v.extend_from_slice(s.as_bytes());
    v.push(0);
    v
}

/// A DATA submessage carrying a parameter list (PL_CDR_LE) from `writer` to `reader`.
fn pl_data(m: &mut Vec<u8>, reader: [u8; 4], writer: [u8; 4], sn: u32, pl: &[u8]) {
    let mut body = Vec::with_capacity(24 + pl.len());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&16u16.to_le_bytes());
    body.extend_from_slice(&reader);
    body.extend_from_slice(&writer);
    body.extend_from_slice(&0i32.to_le_bytes());
    body.extend_from_slice(&sn.to_le_bytes());
    body.extend_from_slice(&[0x00, 0x03, 0x00, 0x00]);
    body.extend_from_slice(pl);
    submessage(m, 0x15, 0x04, &body);
}

/// An SPDP announcement of the made-up participant `prefix`: all builtin endpoints, its
/// locators ports on 127.0.0.1 where nothing listens, a lease of `lease_s`.
fn spdp_announcement(prefix: [u8; 12], port: u32, lease_s: i32, sn: u32) -> Vec<u8> {
    let mut pl = Vec::new();
    param(&mut pl, 0x0015, &[2, 4]); // PID_PROTOCOL_VERSION
    param(&mut pl, 0x0016, &[0x01, 0x99]); // PID_VENDORID
    let mut guid = prefix.to_vec();
    guid.extend_from_slice(&[0, 0, 1, 0xc1]);
    param(&mut pl, 0x0050, &guid); // PID_PARTICIPANT_GUID
    param(&mut pl, 0x0032, &udpv4_locator(port)); // PID_METATRAFFIC_UNICAST_LOCATOR
    param(&mut pl, 0x0031, &udpv4_locator(port + 1)); // PID_DEFAULT_UNICAST_LOCATOR
    let mut lease = lease_s.to_le_bytes().to_vec();
    lease.extend_from_slice(&0u32.to_le_bytes());
    param(&mut pl, 0x0002, &lease); // PID_PARTICIPANT_LEASE_DURATION
    param(&mut pl, 0x0058, &0x0000_0c3fu32.to_le_bytes()); // PID_BUILTIN_ENDPOINT_SET
    param(&mut pl, 0x0001, &[]); // PID_SENTINEL
    let mut m = rtps_header(&prefix);
    pl_data(&mut m, [0x00, 0x01, 0x00, 0xc7], [0x00, 0x01, 0x00, 0xc2], sn, &pl);
    m
}

/// An SEDP announcement by the made-up participant `prefix` of a reliable reader (`reader`
/// true) or writer of the daemon's `topic` and `ty`, at a port where nothing listens.
fn sedp_endpoint(prefix: [u8; 12], entity: u8, reader: bool, topic: &str, ty: &str, port: u32, sn: u32) -> Vec<u8> {
    let mut pl = Vec::new();
    let mut guid = prefix.to_vec();
    guid.extend_from_slice(&[0, 0, entity, if reader { 0x04 } else { 0x03 }]);
    param(&mut pl, 0x005a, &guid); // PID_ENDPOINT_GUID
    let mut participant = prefix.to_vec();
    participant.extend_from_slice(&[0, 0, 1, 0xc1]);
    param(&mut pl, 0x0050, &participant); // PID_PARTICIPANT_GUID
    param(&mut pl, 0x0005, &cdr_string(topic)); // PID_TOPIC_NAME
    param(&mut pl, 0x0007, &cdr_string(ty)); // PID_TYPE_NAME
    let mut reliability = 2u32.to_le_bytes().to_vec(); // RELIABLE
    reliability.extend_from_slice(&[0; 8]);
    param(&mut pl, 0x001a, &reliability); // PID_RELIABILITY
    param(&mut pl, 0x002f, &udpv4_locator(port)); // PID_UNICAST_LOCATOR
    param(&mut pl, 0x0001, &[]);
    let mut m = rtps_header(&prefix);
    let (r, w) = if reader {
        ([0x00, 0x00, 0x04, 0xc7], [0x00, 0x00, 0x04, 0xc2])
    } else {
        ([0x00, 0x00, 0x03, 0xc7], [0x00, 0x00, 0x03, 0xc2])
    };
    pl_data(&mut m, r, w, sn, &pl);
    m
}

/// A message of one to four random submessages of any kind, often malformed (lengths that lie,
/// fields cut short, unknown flags), or a header cut short.
fn random_message(rng: &mut Rng, prefix: [u8; 12]) -> Vec<u8> {
    let mut m = rtps_header(&prefix);
    if rng.below(40) == 0 {
        m.truncate(rng.below(20) as usize);
        return m;
    }
    for _ in 0..1 + rng.below(4) {
        let mut body = Vec::with_capacity(64);
        let id = match rng.below(13) {
            0 => {
                // DATA: serialized payload of random bytes, sometimes inline QoS claimed.
                body.extend_from_slice(&0u16.to_le_bytes());
                body.extend_from_slice(&16u16.to_le_bytes());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                let n = rng.below(200) as usize;
                body.extend_from_slice(&rng.bytes(n));
                0x15
            }
            1 => {
                // DATA_FRAG: any fragment of any declared size.
                body.extend_from_slice(&0u16.to_le_bytes());
                body.extend_from_slice(&28u16.to_le_bytes());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&(rng.below(8) as u32).to_le_bytes());
                body.extend_from_slice(&(rng.below(3) as u16).to_le_bytes());
                body.extend_from_slice(&[16u16, 64, 1024, 0][rng.below(4) as usize].to_le_bytes());
                body.extend_from_slice(&(rng.next() as u32 >> rng.below(32)).to_le_bytes());
                let n = rng.below(200) as usize;
                body.extend_from_slice(&rng.bytes(n));
                0x16
            }
            2 => {
                // HEARTBEAT: any range.
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                0x07
            }
            3 => {
                // ACKNACK: any base, any bitmap of any declared size.
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                let bits = [0u32, 1, 32, 256, 257, u32::MAX][rng.below(6) as usize];
                body.extend_from_slice(&bits.to_le_bytes());
                let n = 4 * rng.below(9) as usize;
                body.extend_from_slice(&rng.bytes(n));
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                0x06
            }
            4 => {
                // NACK_FRAG
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                let bits = [0u32, 1, 32, 256, 257][rng.below(5) as usize];
                body.extend_from_slice(&bits.to_le_bytes());
                let n = 4 * rng.below(9) as usize;
                body.extend_from_slice(&rng.bytes(n));
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                0x12
            }
            5 => {
                // GAP
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&rng.seq());
                let bits = [0u32, 32, 256][rng.below(3) as usize];
                body.extend_from_slice(&bits.to_le_bytes());
                let n = 4 * rng.below(9) as usize;
                body.extend_from_slice(&rng.bytes(n));
                0x08
            }
            6 => {
                // INFO_TS
                body.extend_from_slice(&rng.bytes(8));
                0x09
            }
            7 => {
                // INFO_DST: another made-up participant, or the unknown one.
                let to = if rng.below(2) == 0 {
                    [0; 12]
                } else {
                    phantom(rng.below(5000))
                };
                body.extend_from_slice(&to);
                0x0e
            }
            8 => {
                // INFO_SRC: continue as another participant.
                body.extend_from_slice(&[0; 4]);
                body.extend_from_slice(&[2, 4, 0x01, 0x99]);
                body.extend_from_slice(&phantom(rng.below(5000)));
                0x0c
            }
            9 => {
                // HEARTBEAT_FRAG
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.entity());
                body.extend_from_slice(&rng.seq());
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                body.extend_from_slice(&(rng.next() as u32).to_le_bytes());
                0x13
            }
            10 => {
                // INFO_REPLY: locators of any count.
                body.extend_from_slice(&(rng.below(4) as u32).to_le_bytes());
                body.extend_from_slice(&udpv4_locator(9000 + rng.below(1000) as u32));
                0x0f
            }
            11 => {
                // A parameter list that is not one: SPDP or SEDP data of random bytes.
                let n = rng.below(120) as usize;
                let pl = rng.bytes(n);
                let (r, w) = [
                    ([0x00, 0x01, 0x00, 0xc7], [0x00, 0x01, 0x00, 0xc2]),
                    ([0x00, 0x00, 0x03, 0xc7], [0x00, 0x00, 0x03, 0xc2]),
                    ([0x00, 0x00, 0x04, 0xc7], [0x00, 0x00, 0x04, 0xc2]),
                    ([0x00, 0x02, 0x00, 0xc7], [0x00, 0x02, 0x00, 0xc2]),
                ][rng.below(4) as usize];
                pl_data(&mut m, r, w, rng.next() as u32, &pl);
                continue;
            }
            _ => {
                // Any submessage id at all, with random bytes.
                let n = rng.below(64) as usize;
                body.extend_from_slice(&rng.bytes(n));
                rng.next() as u8
            }
        };
        let flags = rng.next() as u8 & [0x0f, 0x03, 0xff][rng.below(3) as usize];
        let at = m.len();
        submessage(&mut m, id, flags, &body);
        // Lengths that lie: too short, too long, or zero (to the end of the message).
        match rng.below(10) {
            0 => {
                let len = (body.len() as u16).saturating_sub(1 + rng.below(8) as u16);
                m[at + 2..at + 4].copy_from_slice(&len.to_le_bytes());
            }
            1 => {
                let len = body.len() as u16 + 1 + rng.below(64) as u16;
                m[at + 2..at + 4].copy_from_slice(&len.to_le_bytes());
            }
            2 => m[at + 2..at + 4].copy_from_slice(&0u16.to_le_bytes()),
            3 => m.truncate(at + 4 + rng.below(body.len() as u64 + 1) as usize),
            _ => {}
        }
    }
    m
}

/// A flood of mixed hostile datagrams (an older build, sent 420,000 of them in 4 s, grew to
/// 2.1 GB, filled the journal, and afterwards a new subscriber matched but received nothing):
/// random and malformed submessages of every kind, announcements of made-up participants (SPDP,
/// nearly every one new, with locators where nothing listens and long leases) and of their
/// reliable readers and writers of the daemon's own topics (SEDP), which never acknowledge
/// anything. RustDDS's event loop panicked on an ACKNACK whose set reached past the largest
/// sequence number, its discovery thread took minutes to drain the announcements, and it kept
/// what it observed of every made-up GUID prefix; patched,
/// the daemon stays alive and within a wide memory bound, its log short, and a Cyclone DDS
/// subscriber started afterwards, while the made-up participants are still within their leases,
/// matches every topic and gets a sweep.
#[test]
fn a_flood_of_mixed_hostile_datagrams_leaves_discovery_and_delivery_working() {
    let Some(python) = python(&["cyclonedds"]) else {
        return;
    };
    if !in_private_network("ros2::a_flood_of_mixed_hostile_datagrams_leaves_discovery_and_delivery_working") {
        return;
    }
    // Discovery's two ports (multicast and unicast) and the user traffic's two.
    let FloodTarget {
        dir,
        socket,
        mut daemon,
        pid,
        ports,
    } = FloodTarget::start("ros2-mixed", 4);
    let log = || std::fs::read_to_string(dir.join("sqscand.log")).unwrap_or_default();
    // A moment for the node to settle (its own announcements, its topics).
    std::thread::sleep(Duration::from_millis(500));
    let before = rss_kb(pid).unwrap();

    const TOPICS: [(&str, &str); 6] = [
        ("rt/sqscan/points", "sensor_msgs::msg::dds_::PointCloud2_"),
        ("rt/sqscan/joint_states", "sensor_msgs::msg::dds_::JointState_"),
        ("rt/sqscan/detections", "vision_msgs::msg::dds_::Detection3DArray_"),
        ("rt/sqscan/markers", "visualization_msgs::msg::dds_::MarkerArray_"),
        ("rt/sqscan/range", "sensor_msgs::msg::dds_::Image_"),
        ("rt/tf_static", "tf2_msgs::msg::dds_::TFMessage_"),
    ];
    // Made-up participants: so many that nearly every announcement is of a new one, each at
    // its own closed ports on 127.0.0.1; a quarter of the datagrams announce one.
    const PHANTOMS: u64 = 1_000_000;
    const DATAGRAMS: u64 = 300_000;
    let closed_port = |p: u64| 20000 + 2 * (p as u32 % 10000);
    let mut rng = Rng(0x5eed0ff100d);
    let out = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut peak = before;
    let mut sent = 0u64;
    let t0 = Instant::now();
    for i in 0..DATAGRAMS {
        let p = rng.below(PHANTOMS);
        let prefix = phantom(p);
        let datagram = match rng.below(20) {
            0..=4 => {
                let lease = if rng.below(4) == 0 {
                    1 + rng.below(30) as i32
                } else {
                    600
                };
                spdp_announcement(prefix, closed_port(p), lease, 1 + rng.below(1000) as u32)
            }
            5 => {
                let (topic, ty) = TOPICS[rng.below(TOPICS.len() as u64) as usize];
                let reader = rng.below(4) != 0;
                let entity = 1 + rng.below(16) as u8;
                sedp_endpoint(
                    prefix,
                    entity,
                    reader,
                    topic,
                    ty,
                    closed_port(p) + 1,
                    1 + rng.below(1000) as u32,
                )
            }
            _ => random_message(&mut rng, prefix),
        };
        let port = ports[(i % ports.len() as u64) as usize];
        if out.send_to(&datagram, ("127.0.0.1", port)).is_ok() {
            sent += 1;
        }
        if i % 2000 == 1999 {
            // Paced a little, so that the daemon reads a good part of them, and watched.
            std::thread::sleep(Duration::from_millis(2));
            peak = peak.max(rss_kb(pid).unwrap_or(0));
        }
        if t0.elapsed() > Duration::from_secs(8) {
            break;
        }
    }
    let flood = t0.elapsed();
    peak = peak.max(peak_rss_kb(pid, Duration::from_secs(3)));
    let status = daemon.0.try_wait().unwrap();
    let lines = log().lines().count();
    eprintln!(
        "{sent} mixed datagrams to ports {ports:?} in {flood:?}: VmRSS {before} kB before, peak \
         {peak} kB, {lines} lines of log, exit {status:?}"
    );
    assert!(status.is_none(), "the daemon died of the flood: {status:?}\n{}", log());
    // A passing run (in a test build) starts near 17 MB and peaks near 95 MB, mostly the
    // announced made-up participants, kept until their leases run out. The bound is five times
    // that, far below the gigabytes of the failure.
    assert!(
        peak < 512 * 1024,
        "VmRSS went from {before} kB to {peak} kB under the flood"
    );
    assert!(lines < 200, "{lines} lines of log:\n{}", log());

    // Discovery and delivery still work, the made-up participants still within their leases.
    let t2 = Instant::now();
    let m = subscriber_gets_a_sweep(&python, &socket, 40, &log);
    eprintln!("the subscriber after the flood took {:?}", t2.elapsed());
    // Joint states arrive too: all 150 of the sweep's in every run since the discovery fixes,
    // but in one run before them two went missing and were not repaired within the
    // subscriber's wait, so only their arrival is required here.
    assert!(
        !m["joints"].as_array().unwrap().is_empty(),
        "joint states after the flood: {m}"
    );
    let after = rss_kb(pid).unwrap_or(0);
    eprintln!(
        "VmRSS {after} kB after the subscriber, {} lines of log",
        log().lines().count()
    );
    assert!(daemon.0.try_wait().unwrap().is_none(), "{}", log());
}
