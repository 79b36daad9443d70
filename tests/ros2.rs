//! ROS 2 over DDS (the `ros2` feature), seen by an independent DDS implementation: Eclipse
//! Cyclone DDS from PyPI (`cyclonedds`), with its own IDL definitions of the messages
//! (`tests/py/dds_sub.py`). DDS discovers by multicast, so the test runs inside a private network
//! namespace with only loopback (it says SKIPPED where none can be had). Without that Python it
//! says it skipped, unless `SQSCAN_REQUIRE_PYTHON_TOOLS` is set (as `scripts/test.sh` sets it).
#![cfg(feature = "ros2")]

use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

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
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
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
    if !in_private_network("a_data_frag_flood_declaring_4_gib_samples_costs_bounded_memory") {
        return;
    }
    let dir = tmpdir("ros2-datafrag");
    let scene = root().join("scenes/fig3_table.toml");
    let config = format!(
        "[sim]\nscene = {scene:?}\nseed = 3\nrealtime = false\n[acquisition]\nmode = \"on_demand\"\n\
         [ros2]\nnode = \"scanner\"\n"
    );
    std::fs::write(dir.join("sqscand.toml"), config).unwrap();
    let socket = dir.join("sqscand.sock");
    let mut daemon = sqscand(&dir, "sqscand", &[]);
    let pid = daemon.0.id();
    let log = || std::fs::read_to_string(dir.join("sqscand.log")).unwrap_or_default();
    let mut ports = Vec::new();
    wait_for("the daemon's DDS ports", Duration::from_secs(30), || {
        ports = dds_ports(pid);
        ports.len() >= 2
    });
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
    let t1 = Instant::now();
    while t1.elapsed() < Duration::from_secs(3) {
        peak = peak.max(rss_kb(pid).unwrap_or(0));
        std::thread::sleep(Duration::from_millis(20));
    }
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
    let out = Command::new(&python)
        .arg(root().join("tests/py/dds_sub.py"))
        .arg(&socket)
        .arg("cup")
        .arg("60")
        .output()
        .unwrap();
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
    assert_eq!(m["reply"]["found"], true, "{}", m["reply"]);
    assert_eq!(m["clouds"].as_array().unwrap().len(), 1, "a sweep after the flood: {m}");
    assert!(daemon.0.try_wait().unwrap().is_none(), "{}", log());
}
