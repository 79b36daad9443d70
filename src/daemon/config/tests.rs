//! The configuration file's parsing and the errors that name its fields.

use super::*;
use sqscan_drivers::gige::FeatureValue;

fn parse(text: &str) -> Result<Config, SpecError> {
    Config::from_toml_str(text, Path::new("/etc/sqscan/sqscand.toml"))
}

#[test]
fn empty_file_is_the_simulator() {
    let c = parse("").unwrap();
    assert!(matches!(c.backend, BackendConfig::Sim { .. }));
    assert!(c.continuous);
    assert_eq!(c.socket_mode, 0o660);
}

#[test]
fn hardware_paths_are_relative_to_the_file() {
    let c = parse(
        r#"
        [server]
        socket = "/run/sqscan/sqscand.sock"
        tcp = "127.0.0.1:2948"
        [hardware]
        calibration = "rig.toml"
        ptu = { path = "/dev/ttyS0", protocol = "flir" }
        sensor = { tcp = "10.0.0.2:5000" }
        [sweep]
        tilt_from_rad = 0.5
        tilt_to_rad = 0.8
        speed_rad_s = 0.1
        [watch]
        objects = ["cup"]
        "#,
    )
    .unwrap();
    let BackendConfig::Hardware(h) = &c.backend else {
        panic!("{:?}", c.backend)
    };
    assert_eq!(h.calibration, Path::new("/etc/sqscan/rig.toml"));
    assert_eq!(h.ptu_kind, PtuKind::Flir);
    assert_eq!(h.ptu_baud, 9600);
    assert_eq!(h.sensor, SensorEndpoint::Tcp("10.0.0.2:5000".into()));
    assert_eq!(c.tcp, Some("127.0.0.1:2948".parse().unwrap()));
    assert_eq!(c.watch, vec!["cup".to_string()]);
    assert_eq!(c.frame_id, "base_link");
    assert_eq!(
        parse("[server]\nframe_id = \"robot/base_footprint\"").unwrap().frame_id,
        "robot/base_footprint"
    );
}

#[test]
fn a_replay_table_replays_from_a_directory_beside_the_file() {
    let c = parse("[replay]\ndir = \"recordings\"").unwrap();
    assert_eq!(
        c.backend,
        BackendConfig::Replay {
            dir: PathBuf::from("/etc/sqscan/recordings"),
            speed: 1.0,
            looping: false
        }
    );
    let c = parse("[acquisition]\nbackend = \"replay\"\n[replay]\ndir = \"/r\"\nspeed = 0\nloop = true").unwrap();
    assert_eq!(
        c.backend,
        BackendConfig::Replay {
            dir: PathBuf::from("/r"),
            speed: 0.0,
            looping: true
        }
    );
}

#[test]
fn errors_name_the_field() {
    for (text, field) in [
        ("[acquisition]\nmode = \"sometimes\"", "acquisition.mode"),
        ("[server]\ntcp = \"localhost\"", "server.tcp"),
        ("[server]\nsocket_mode = 0o1777", "server.socket_mode"),
        ("[sweep]\nspeed_rad_s = -1.0", "sweep.speed_rad_s"),
        ("[acquisition]\nbackend = \"hardware\"", "hardware"),
        (
            "[hardware]\ncalibration = \"c\"\nptu = { path = \"p\", protocol = \"visca\" }\nsensor = { path = \"s\" }",
            "hardware.ptu.protocol",
        ),
        (
            "[hardware]\ncalibration = \"c\"\nptu = { path = \"p\", protocol = \"flir\" }\nsensor = { path = \"s\" }",
            "sweep",
        ),
        (
            "[hardware]\ncalibration = \"c\"\nptu = { path = \"p\", protocol = \"powercube\", tilt_module = 0 }\nsensor = { path = \"s\" }",
            "hardware.ptu.tilt_module",
        ),
    ] {
        let e = parse(text).unwrap_err().to_string();
        assert!(e.contains(field), "{text:?}: {e}");
        assert!(e.contains("sqscand.toml"), "{e}");
    }
    // Unknown keys are caught by the parser with their line.
    let e = parse("[server]\nsokcet = \"x\"").unwrap_err().to_string();
    assert!(e.contains("sokcet"), "{e}");
}

/// Each of these passed, and some made `--check` itself panic
/// (`Duration::from_secs_f64(1e20)`), killed a task at start (a pool of 2^62 threads, a
/// sweep at 1e-300 rad/s) or left the daemon sweeping forever with nothing logged.
#[test]
fn absurd_numbers_are_refused_naming_the_field() {
    for (text, field) in [
        ("[sweep]\npause_s = 1e20", "sweep.pause_s"),
        ("[sweep]\npause_s = -1.0", "sweep.pause_s"),
        ("[sweep]\ntimeout_s = 1e20", "sweep.timeout_s"),
        ("[sweep]\nspeed_rad_s = 1e-300", "sweep.speed_rad_s"),
        ("[sweep]\ntilt_from_rad = -1e9", "sweep.tilt_from_rad"),
        ("[sweep]\ntilt_to_rad = 1e9", "sweep.tilt_to_rad"),
        ("[sweep]\npan_rad = nan", "sweep.pan_rad"),
        ("[sweep]\nmin_profiles = 1", "sweep.min_profiles"),
        ("[detect]\nworkers = 4611686018427387904", "detect.workers"),
        ("[detect]\nmax_range_m = 1e300", "detect.max_range_m"),
        ("[server]\nmax_clients = 4611686018427387904", "server.max_clients"),
        ("[server]\nmax_clients = 0", "server.max_clients"),
        ("[server]\nclient_queue = 4611686018427387904", "server.client_queue"),
        ("[server]\nidle_timeout_s = 1e20", "server.idle_timeout_s"),
        ("[server]\nidle_timeout_s = 0.0", "server.idle_timeout_s"),
        ("[server]\ntcp = \"0.0.0.0:29481\"", "server.tcp"),
        ("[server]\ntcp = \"[::]:29481\"\nallow_remote = false", "server.tcp"),
        ("[record]\ndir = \"r\"\nkeep = 4611686018427387904", "record.keep"),
        ("[replay]\ndir = \"r\"\nspeed = -1.0", "replay.speed"),
        ("[server]\nframe_id = \"\"", "server.frame_id"),
        ("[server]\nframe_id = \"base link\"", "server.frame_id"),
        ("[server]\nframe_id = \"9base\"", "server.frame_id"),
        ("[replay]\ndir = \"r\"\nspeed = inf", "replay.speed"),
        ("[acquisition]\nbackend = \"replay\"", "replay"),
        ("[acquisition]\nbackend = \"tape\"", "acquisition.backend"),
        ("[gripper]\nfriction = -0.5", "gripper.friction"),
        ("[gripper]\nmax_opening = 1e300", "gripper.max_opening"),
        (
            "[gripper]\nmax_opening = 0.02\nmin_opening = 0.03",
            "gripper.min_opening",
        ),
        ("[gripper]\npalm = [0.1, 0.0, 0.05]", "gripper.palm[1]"),
        ("[gripper]\nfinger = 0.1", "finger"),
        (
            "[replay]\ndir = \"r\"\n[hardware]\ncalibration = \"c\"\nptu = { path = \"p\", protocol = \"flir\" }\nsensor = { path = \"s\" }",
            "acquisition.backend",
        ),
        (
            "[sweep]\ntilt_from_rad = -3.0\ntilt_to_rad = 3.0\nspeed_rad_s = 0.001",
            "sweep.speed_rad_s",
        ),
    ] {
        let e = parse(text).unwrap_err().to_string();
        assert!(e.contains(field), "{text:?}: {e}");
    }
    // A remote address when asked for.
    let c = parse("[server]\ntcp = \"0.0.0.0:29481\"\nallow_remote = true").unwrap();
    assert_eq!(c.tcp, Some("0.0.0.0:29481".parse().unwrap()));
    // A gripper of its own, the keys left out at their defaults.
    let c = parse("[gripper]\nmax_opening = 0.14\nfriction = 0.8").unwrap();
    assert_eq!(c.gripper.max_opening, 0.14);
    assert_eq!(c.gripper.finger_depth, crate::grasp::Gripper::default().finger_depth);
    // The ends of the ranges are accepted.
    parse("[sweep]\npause_s = 3600.0\ntimeout_s = 3600.0\n[detect]\nworkers = 256\n[server]\nmax_clients = 65536")
        .unwrap();
}

#[test]
fn the_shipped_example_parses() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("systemd/sqscand.toml");
    let c = Config::from_file(&path).unwrap();
    assert!(matches!(c.backend, BackendConfig::Hardware(_)));
    assert_eq!(c.socket, Path::new("/run/sqscan/sqscand.sock"));
    assert_eq!(
        c.watch,
        ["bowl".to_string(), "cup".to_string()]
            .iter()
            .rev()
            .cloned()
            .collect::<Vec<_>>()
    );
    assert_eq!(c.record_keep, 20);
}

const GIGE: &str = r#"
[hardware]
calibration = "rig.toml"
ptu = { path = "/dev/ttyS0", protocol = "powercube" }
[hardware.sensor]
kind = "gige"
address = "192.168.10.20"
rows_per_frame = 16
stamp = "last_row"
features = [
  { name = "DeviceScanType", value = "Linescan3D" },
  { name = "ExposureTime", value = 50.0 },
  { name = "Scan3dInvalidDataFlag", value = true },
  { name = "AcquisitionLineRate", value = 1000 },
]
[sweep]
tilt_from_rad = 0.5
tilt_to_rad = 0.8
speed_rad_s = 0.1
"#;

#[test]
fn a_gige_vision_camera_by_address_and_features_by_name() {
    let parsed = parse(GIGE);
    if !cfg!(feature = "gige") {
        let e = parsed.unwrap_err().to_string();
        assert!(e.contains("hardware.sensor.kind") && e.contains("feature gige"), "{e}");
        return;
    }
    let c = parsed.unwrap();
    let BackendConfig::Hardware(h) = &c.backend else {
        panic!("{:?}", c.backend)
    };
    let SensorEndpoint::Gige(g) = &h.sensor else {
        panic!("{:?}", h.sensor)
    };
    assert_eq!(h.sensor.to_string(), "gige://192.168.10.20");
    assert_eq!(g.rows_per_frame, Some(16));
    assert!(g.stamp_last_row);
    assert_eq!(
        g.features,
        vec![
            ("DeviceScanType".to_string(), FeatureValue::Str("Linescan3D".into())),
            ("ExposureTime".to_string(), FeatureValue::Float(50.0)),
            ("Scan3dInvalidDataFlag".to_string(), FeatureValue::Bool(true)),
            ("AcquisitionLineRate".to_string(), FeatureValue::Int(1000)),
        ]
    );
}

#[test]
fn gige_settings_that_make_no_sense_are_named() {
    let sqpf = "[hardware]\ncalibration = \"c\"\nptu = { path = \"p\", protocol = \"flir\" }\n[hardware.sensor]\n";
    let mut cases = vec![
        (
            format!("{sqpf}path = \"s\"\naddress = \"10.0.0.1\""),
            "hardware.sensor.address",
        ),
        (format!("{sqpf}kind = \"usb3\"\npath = \"s\""), "hardware.sensor.kind"),
    ];
    if cfg!(feature = "gige") {
        cases.extend([
            (format!("{sqpf}kind = \"gige\""), "hardware.sensor.address"),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\npath = \"s\""),
                "hardware.sensor.path",
            ),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\nrows_per_frame = 0"),
                "hardware.sensor.rows_per_frame",
            ),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\nstamp = \"middle\""),
                "hardware.sensor.stamp",
            ),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\nfeatures = [{{ name = \"Gain\", value = [1, 2] }}]"),
                "hardware.sensor.features[0]",
            ),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\nfeatures = [{{ name = \"Gain; rm\", value = 1 }}]"),
                "hardware.sensor.features[0]",
            ),
            (
                format!("{sqpf}kind = \"gige\"\naddress = \"a\"\nfeatures = [{{ name = \"Gain\", value = nan }}]"),
                "hardware.sensor.features[0]",
            ),
        ]);
    }
    for (text, field) in cases {
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains(field), "{text:?}: {e}");
    }
}

/// `[record] mcap` needs the `mcap` feature: a daemon built without it says so, naming the key,
/// instead of recording nothing.
#[test]
fn mcap_recording_is_on_only_where_it_was_built() {
    let r = parse("[record]\ndir = \"r\"\nmcap = true");
    if cfg!(feature = "mcap") {
        assert!(r.unwrap().record_mcap);
    } else {
        let e = r.unwrap_err().to_string();
        assert!(e.contains("record.mcap") && e.contains("feature"), "{e}");
    }
    assert!(!parse("[record]\ndir = \"r\"").unwrap().record_mcap);
}

/// `[foxglove] listen`: an address and port on loopback (the protocol has no authentication),
/// in a build with the `foxglove` feature; anything else is refused naming the key.
#[test]
fn the_live_view_listens_on_loopback_only() {
    for bad in [
        "localhost",
        "0.0.0.0:8765",
        "192.168.1.5:8765",
        "[::]:8765",
        "127.0.0.1:99999",
    ] {
        let e = parse(&format!("[foxglove]\nlisten = \"{bad}\""))
            .unwrap_err()
            .to_string();
        assert!(e.contains("foxglove.listen"), "{bad}: {e}");
    }
    let r = parse("[foxglove]\nlisten = \"127.0.0.1:8765\"");
    if cfg!(feature = "foxglove") {
        assert_eq!(r.unwrap().foxglove_listen, Some("127.0.0.1:8765".parse().unwrap()));
        assert!(parse("[foxglove]\nlisten = \"[::1]:8765\"").is_ok());
    } else {
        let e = r.unwrap_err().to_string();
        assert!(e.contains("foxglove.listen") && e.contains("feature"), "{e}");
    }
    assert_eq!(parse("").unwrap().foxglove_listen, None);
}

/// `[foxglove] backlog_mb`: a viewer's queue bound, 1 to 1024 MB, 32 by default.
#[test]
fn the_view_backlog_is_bounded() {
    if !cfg!(feature = "foxglove") {
        return;
    }
    let view = |extra: &str| parse(&format!("[foxglove]\nlisten = \"127.0.0.1:8765\"\n{extra}"));
    assert_eq!(view("").unwrap().foxglove_backlog_bytes, 32 << 20);
    assert_eq!(view("backlog_mb = 4").unwrap().foxglove_backlog_bytes, 4 << 20);
    for bad in ["0", "1025", "-1", "1e12"] {
        let e = view(&format!("backlog_mb = {bad}")).unwrap_err().to_string();
        assert!(e.contains("backlog_mb"), "{bad}: {e}");
    }
}

/// `[ros2]`: names as ROS 2 takes them, a domain whose ports exist, a depth within bounds and
/// the QoS words ROS 2 uses; each refused value names its key. Without the `ros2` feature the
/// table itself is refused, naming the feature.
#[test]
fn the_ros2_table_is_validated_key_by_key() {
    for (bad, key) in [
        ("domain_id = 233", "ros2.domain_id"),
        ("domain_id = -1", "domain_id"),
        ("node = \"\"", "ros2.node"),
        ("node = \"my node\"", "ros2.node"),
        ("node = \"a/b\"", "ros2.node"),
        ("node = \"9lives\"", "ros2.node"),
        ("namespace = \"robot\"", "ros2.namespace"),
        ("namespace = \"/robot/\"", "ros2.namespace"),
        ("points = \"/sqscan//points\"", "ros2.points"),
        ("points = \"/sqscan/points/\"", "ros2.points"),
        ("joint_states = \"/a__b\"", "ros2.joint_states"),
        ("detections = \"/sqscan/1st\"", "ros2.detections"),
        ("detections = \"~/private\"", "ros2.detections"),
        ("markers = \"/sqscan/markers!\"", "ros2.markers"),
        ("range = \"\"", "ros2.range"),
        ("reliability = \"sometimes\"", "ros2.reliability"),
        ("durability = \"persistent\"", "ros2.durability"),
        ("depth = 0", "ros2.depth"),
        ("depth = 21", "ros2.depth"),
        ("depth = 100000", "ros2.depth"),
        ("max_received_sample_kib = 63", "ros2.max_received_sample_kib"),
        ("max_received_sample_kib = 4194304", "ros2.max_received_sample_kib"),
        ("publish_tf = \"yes\"", "publish_tf"),
        ("topic = \"/x\"", "topic"),
    ] {
        let e = parse(&format!("[ros2]\n{bad}")).unwrap_err().to_string();
        assert!(e.contains(key), "{bad}: {e}");
    }
    let r = parse(
        "[ros2]\ndomain_id = 42\nnode = \"scanner_1\"\nnamespace = \"/robot1\"\npoints = \"cloud\"\n\
         reliability = \"best_effort\"\ndurability = \"transient_local\"\ndepth = 2\n\
         max_received_sample_kib = 256\npublish_tf = false",
    );
    if cfg!(feature = "ros2") {
        let c = r.unwrap().ros2.unwrap();
        assert_eq!(c.domain_id, 42);
        assert_eq!((c.node.as_str(), c.namespace.as_str()), ("scanner_1", "/robot1"));
        assert_eq!(c.points, "cloud");
        assert_eq!(c.detections, "/sqscan/detections");
        assert!(!c.reliable && c.transient_local);
        assert_eq!(c.depth, 2);
        assert_eq!(c.max_received_sample, 256 * 1024);
        assert!(!c.publish_tf);
        assert_eq!(parse("[ros2]").unwrap().ros2, Some(super::Ros2Config::default()));
        assert!(super::Ros2Config::default().publish_tf);
    } else {
        let e = r.unwrap_err().to_string();
        assert!(e.contains("ros2") && e.contains("feature"), "{e}");
    }
    assert_eq!(parse("").unwrap().ros2, None);
}
