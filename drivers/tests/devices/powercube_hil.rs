//! Hardware-in-the-loop tests: the real PowerCube driver against the mock unit over real
//! pseudo-terminals. The driver opens the pty slave by path, exactly as it opens a serial port.
//!
//! The machine running these may be loaded: timeouts are generous, assertions are about
//! correctness rather than speed, and waiting is always "poll until a condition, with a
//! deadline", never a bare sleep.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sqscan_drivers::mock::{Faults, MockPort, MockPowerCube, MockPowerCubeConfig, ServeEnd};
use sqscan_drivers::powercube::{Joint, PowerCubeConfig, PowerCubePtu};
use sqscan_drivers::{Error, Goal, PanTilt, PositionSample, SerialLink};
use tokio::task::JoinHandle;

const MOVE_TIMEOUT: Duration = Duration::from_secs(30);

struct Mock {
    path: PathBuf,
    device: Arc<Mutex<MockPowerCube>>,
    task: JoinHandle<std::io::Result<ServeEnd>>,
}

fn start_mock(cfg: MockPowerCubeConfig, faults: Faults, link: Option<&Path>) -> Mock {
    let port = MockPort::create(link).expect("a pty");
    let path = port.path().to_owned();
    let device = Arc::new(Mutex::new(MockPowerCube::new(cfg)));
    let task = tokio::spawn(port.serve(device.clone(), faults));
    Mock { path, device, task }
}

fn driver_config() -> PowerCubeConfig {
    PowerCubeConfig {
        // Far more than a pty needs: the test machine may be busy.
        reply_timeout: Duration::from_millis(500),
        retries: 3,
        acceleration_rad_s2: 3.0,
        ..PowerCubeConfig::default()
    }
}

async fn open(path: &Path) -> PowerCubePtu<SerialLink> {
    PowerCubePtu::open(path, driver_config())
        .await
        .expect("driver starts on the mock")
}

fn mock_angles(mock: &Mock) -> (f64, f64) {
    use sqscan_drivers::mock::MockDevice;
    mock.device.lock().unwrap().joint_angles(Instant::now())
}

fn temp_link(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sqscan-hil-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join("ptu")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn home_clears_a_halt_and_a_move_reaches_the_goal() {
    let mut cfg = MockPowerCubeConfig::default();
    cfg.tilt.initial_rad = 0.2;
    cfg.pan.initial_rad = -0.1;
    let mock = start_mock(cfg, Faults::default(), None);
    let mut ptu = open(&mock.path).await;

    ptu.halt().await.unwrap();
    let state = ptu.state().await.unwrap();
    assert!(state.tilt.fault && !state.tilt.homed, "{state:?}");
    let home = ptu.home().await.unwrap();
    assert!(home.pan_rad.abs() < 1e-4 && home.tilt_rad.abs() < 1e-4, "{home:?}");
    let state = ptu.state().await.unwrap();
    assert!(state.pan.homed && state.tilt.homed && !state.tilt.fault, "{state:?}");

    let goal = Goal {
        pan_rad: 0.1,
        tilt_rad: 0.3,
        speed_rad_s: 0.8,
    };
    let end = ptu.move_and_track(goal, None, MOVE_TIMEOUT).await.unwrap();
    assert!((end.tilt_rad - 0.3).abs() < 1e-3 && (end.pan_rad - 0.1).abs() < 1e-3);
    let (pan, tilt) = mock_angles(&mock);
    assert!(
        (pan - 0.1).abs() < 1e-6 && (tilt - 0.3).abs() < 1e-6,
        "mock at {pan} {tilt}"
    );
    let state = ptu.state().await.unwrap();
    assert!(
        !state.tilt.moving && state.tilt.detail.contains("RAMP_END"),
        "{state:?}"
    );

    // A goal beyond the limits the driver read from the modules is refused before sending.
    let far = Goal { tilt_rad: 3.0, ..goal };
    assert!(matches!(ptu.move_to(far).await, Err(Error::OutOfRange { .. })));
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn position_samples_follow_the_ramp() {
    let mock = start_mock(MockPowerCubeConfig::default(), Faults::default(), None);
    let mut ptu = open(&mock.path).await;
    let speed = 0.5;
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let goal = Goal {
        pan_rad: 0.0,
        tilt_rad: 0.6,
        speed_rad_s: speed,
    };
    let end = ptu.move_and_track(goal, Some(&tx), MOVE_TIMEOUT).await.unwrap();
    drop(tx);
    let mut samples: Vec<PositionSample> = Vec::new();
    while let Some(s) = rx.recv().await {
        samples.push(s);
    }
    assert!((end.tilt_rad - 0.6).abs() < 1e-3);
    // ~1.3 s of motion at 50 Hz; even a starved host gets a handful of samples in.
    assert!(samples.len() >= 5, "{} samples", samples.len());
    let inside = samples
        .iter()
        .filter(|s| s.tilt_rad > 0.05 && s.tilt_rad < 0.55)
        .count();
    assert!(inside >= 2, "only {inside} samples during the ramp");
    for w in samples.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert!(b.t > a.t && b.tilt_rad >= a.tilt_rad - 1e-6, "{a:?} -> {b:?}");
        // The joint moved no faster than the ramp speed, allowing for each stamp's uncertainty
        // (half its span) and for the mock integrating its motion in 1 ms steps.
        let dt = (b.t - a.t).as_secs_f64() + (a.span + b.span).as_secs_f64() / 2.0 + 2e-3;
        assert!(b.tilt_rad - a.tilt_rad <= speed * dt + 1e-4, "{a:?} -> {b:?}");
    }
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_reply_is_retried() {
    let faults = Faults {
        drop_every: 3,
        ..Faults::default()
    };
    let mock = start_mock(MockPowerCubeConfig::default(), faults, None);
    let mut ptu = open(&mock.path).await;
    for _ in 0..6 {
        let s = ptu.position().await.unwrap();
        assert_eq!((s.pan_rad, s.tilt_rad), (0.0, 0.0));
    }
    let stats = ptu.stats();
    assert!(stats.timeouts >= 3 && stats.retries >= 3, "{stats:?}");
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_checksum_is_rejected() {
    // Every reply corrupted: nothing gets through, and the error says why.
    let always = Faults {
        corrupt_every: 1,
        ..Faults::default()
    };
    let mock = start_mock(MockPowerCubeConfig::default(), always, None);
    let err = PowerCubePtu::open(&mock.path, driver_config())
        .await
        .err()
        .expect("no good reply, no driver");
    assert!(err.is_checksum(), "{err}");
    mock.task.abort();

    // Every fourth reply corrupted: each is rejected, retried, and the values are right.
    let sometimes = Faults {
        corrupt_every: 4,
        ..Faults::default()
    };
    let mut cfg = MockPowerCubeConfig::default();
    cfg.tilt.initial_rad = 0.25;
    let mock = start_mock(cfg, sometimes, None);
    let mut ptu = open(&mock.path).await;
    for _ in 0..5 {
        assert_eq!(ptu.joint_position(Joint::Tilt).await.unwrap(), 0.25);
    }
    assert!(ptu.stats().frame_errors >= 2, "{:?}", ptu.stats());
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_before_every_reply_is_skipped() {
    let faults = Faults {
        garbage_every: 1,
        delay: Duration::from_millis(5),
        seed: 7,
        ..Faults::default()
    };
    let mock = start_mock(MockPowerCubeConfig::default(), faults, None);
    let mut ptu = open(&mock.path).await;
    let goal = Goal {
        pan_rad: -0.2,
        tilt_rad: 0.1,
        speed_rad_s: 1.0,
    };
    let end = ptu.move_and_track(goal, None, MOVE_TIMEOUT).await.unwrap();
    assert!((end.pan_rad + 0.2).abs() < 1e-3 && (end.tilt_rad - 0.1).abs() < 1e-3);
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unplugged_device_is_reported_and_reconnects_when_back() {
    let link = temp_link("unplug");
    let mock = start_mock(MockPowerCubeConfig::default(), Faults::default(), Some(&link));
    let mut ptu = open(&link).await;
    ptu.position().await.unwrap();

    // Unplug: the mock's task ends and the pty master closes.
    mock.task.abort();
    let _ = mock.task.await;
    assert!(matches!(ptu.position().await, Err(Error::Disconnected)));

    // Plug a new unit in at the same link; the driver reopens the path.
    let mut cfg = MockPowerCubeConfig::default();
    cfg.tilt.initial_rad = 0.4;
    let mock = start_mock(cfg, Faults::default(), Some(&link));
    ptu.reconnect().await.unwrap();
    // Positions travel as f32.
    assert_eq!(ptu.joint_position(Joint::Tilt).await.unwrap(), f64::from(0.4f32));

    // The unplug fault: after 12 more replies the mock closes the line by itself.
    mock.task.abort();
    let faults = Faults {
        disconnect_after: Some(12),
        ..Faults::default()
    };
    let mock = start_mock(MockPowerCubeConfig::default(), faults, Some(&link));
    ptu.reconnect().await.unwrap(); // 4 replies: limits of both modules, ramp acceleration
    let deadline = Instant::now() + Duration::from_secs(30);
    let err = loop {
        match ptu.position().await {
            Ok(_) => assert!(Instant::now() < deadline, "never unplugged"),
            Err(e) => break e,
        }
    };
    assert!(matches!(err, Error::Disconnected), "{err}");
    assert!(matches!(
        mock.task.await.unwrap(),
        Ok(ServeEnd::Unplugged { replies: 12 })
    ));
    let _ = std::fs::remove_dir_all(link.parent().unwrap());
}
