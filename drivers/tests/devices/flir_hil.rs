//! Hardware-in-the-loop tests: the real PTU-D46 driver against the mock unit over real
//! pseudo-terminals. The driver opens the pty slave by path, exactly as it opens a serial port.
//!
//! The machine running these may be loaded: timeouts are generous, assertions are about
//! correctness rather than speed, and waiting is always "poll until a condition, with a
//! deadline", never a bare sleep.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sqscan_drivers::flir::{Axis, AxisQuery, FlirConfig, FlirPtu, PtuCommand, PtuError};
use sqscan_drivers::mock::{Faults, MockFlirConfig, MockFlirPtu, MockPort, ServeEnd};
use sqscan_drivers::{Error, Goal, PanTilt, PositionSample, SerialLink};
use tokio::task::JoinHandle;

const MOVE_TIMEOUT: Duration = Duration::from_secs(30);

struct Mock {
    path: PathBuf,
    device: Arc<Mutex<MockFlirPtu>>,
    task: JoinHandle<std::io::Result<ServeEnd>>,
}

fn start_mock(cfg: MockFlirConfig, faults: Faults, link: Option<&Path>) -> Mock {
    let port = MockPort::create(link).expect("a pty");
    let path = port.path().to_owned();
    let device = Arc::new(Mutex::new(MockFlirPtu::new(cfg)));
    let task = tokio::spawn(port.serve(device.clone(), faults));
    Mock { path, device, task }
}

fn driver_config() -> FlirConfig {
    FlirConfig {
        // Far more than a pty needs: the test machine may be busy.
        reply_timeout: Duration::from_millis(500),
        retries: 3,
        ..FlirConfig::default()
    }
}

async fn open(path: &Path) -> FlirPtu<SerialLink> {
    FlirPtu::open(path, driver_config())
        .await
        .expect("driver starts on the mock")
}

fn mock_steps(mock: &Mock) -> (i64, i64) {
    mock.device.lock().unwrap().steps(Instant::now())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_up_reads_the_unit_and_reset_homes_it() {
    let mut cfg = MockFlirConfig::default();
    cfg.pan.initial_steps = -400;
    cfg.tilt.initial_steps = 300;
    let mock = start_mock(cfg, Faults::default(), None);
    let mut ptu = open(&mock.path).await;
    {
        let dev = mock.device.lock().unwrap();
        assert!(!dev.echo() && dev.terse(), "start-up left echo or sentences on");
    }
    let pan = ptu.axis(Axis::Pan);
    assert_eq!((pan.min_steps, pan.max_steps), (-3090, 3090));
    assert_eq!(ptu.axis(Axis::Tilt).resolution.arcsec_per_step(), 185.1428);
    let limits = ptu.limits();
    assert!((limits.pan_rad.1.to_degrees() - 158.914).abs() < 1e-3, "{limits:?}");

    let s = ptu.position().await.unwrap();
    assert!(s.pan_rad < -0.3 && s.tilt_rad > 0.06, "{s:?}");
    let home = ptu.home().await.unwrap();
    assert_eq!((home.pan_rad, home.tilt_rad), (0.0, 0.0));
    assert_eq!(mock_steps(&mock), (0, 0));
    assert_eq!(ptu.stats().limit_hits, 4, "the reset answer's !T!T!P!P");
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_move_reaches_the_goal_and_samples_follow_it() {
    let mock = start_mock(MockFlirConfig::default(), Faults::default(), None);
    let mut ptu = open(&mock.path).await;
    let speed = 0.5;
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel();
    let goal = Goal {
        pan_rad: 0.3,
        tilt_rad: -0.15,
        speed_rad_s: speed,
    };
    let end = ptu.move_and_track(goal, Some(&tx), MOVE_TIMEOUT).await.unwrap();
    drop(tx);
    let mut samples: Vec<PositionSample> = Vec::new();
    while let Some(s) = rx.recv().await {
        samples.push(s);
    }
    // Whole steps: within half a step of the goal.
    let pan_step = ptu.axis(Axis::Pan).resolution.rad_per_step();
    assert!((end.pan_rad - 0.3).abs() <= pan_step / 2.0, "{end:?}");
    assert!((end.tilt_rad + 0.15).abs() <= pan_step / 2.0, "{end:?}");
    let expected = ptu.axis(Axis::Pan).resolution.rad_to_steps(0.3).unwrap();
    assert_eq!(mock_steps(&mock).0, i64::from(expected));
    // 0.6 s of pan motion at 20 Hz; even a starved host gets a few samples in.
    assert!(samples.len() >= 4, "{} samples", samples.len());
    let inside = samples.iter().filter(|s| s.pan_rad > 0.02 && s.pan_rad < 0.28).count();
    assert!(inside >= 2, "only {inside} samples during the move");
    for w in samples.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert!(b.t > a.t && b.pan_rad >= a.pan_rad, "{a:?} -> {b:?}");
        let dt = (b.t - a.t).as_secs_f64() + (a.span + b.span).as_secs_f64() / 2.0;
        assert!(b.pan_rad - a.pan_rad <= speed * dt + 2.0 * pan_step, "{a:?} -> {b:?}");
    }
    let state = ptu.state().await.unwrap();
    assert!(!state.pan.moving && state.pan.detail.contains("steps/s"), "{state:?}");
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn out_of_range_is_refused_with_a_typed_error() {
    let mock = start_mock(MockFlirConfig::default(), Faults::default(), None);
    let mut ptu = open(&mock.path).await;
    // The driver refuses a goal beyond the limits it read, before sending anything.
    let far = Goal {
        pan_rad: 0.0,
        tilt_rad: 1.0,
        speed_rad_s: 0.5,
    };
    assert!(matches!(ptu.move_to(far).await, Err(Error::OutOfRange { .. })));
    // The unit refuses a raw command beyond its limits with `!`, typed, and nothing moves.
    let err = ptu
        .command(&PtuCommand::SetPosition(Axis::Pan, 3200))
        .await
        .unwrap_err();
    assert!(
        matches!(&err, Error::Ptu(PtuError::OutOfRange(m)) if m.contains("3090")),
        "{err}"
    );
    let err = ptu.command(&PtuCommand::Raw("zz".into())).await.unwrap_err();
    assert!(matches!(err, Error::Ptu(PtuError::IllegalCommand(_))), "{err}");
    assert_eq!(mock_steps(&mock), (0, 0));
    assert_eq!(mock.device.lock().unwrap().refused, 2);
    // The link is still in step afterwards.
    assert_eq!(ptu.query_steps(Axis::Tilt, AxisQuery::MaxPosition).await.unwrap(), 604);
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn lost_and_corrupted_replies_are_retried() {
    let faults = Faults {
        drop_every: 3,
        corrupt_every: 5,
        ..Faults::default()
    };
    let mut cfg = MockFlirConfig::default();
    cfg.tilt.initial_steps = -200;
    let mock = start_mock(cfg, faults, None);
    let mut ptu = open(&mock.path).await;
    for _ in 0..6 {
        let tilt = ptu.query_steps(Axis::Tilt, AxisQuery::Position).await.unwrap();
        assert_eq!(tilt, -200);
    }
    let stats = ptu.stats();
    assert!(stats.timeouts >= 3 && stats.retries >= 3, "{stats:?}");
    assert!(stats.noise_lines >= 1, "{stats:?}");
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_before_every_reply_is_skipped() {
    let faults = Faults {
        garbage_every: 1,
        delay: Duration::from_millis(2),
        seed: 7,
        ..Faults::default()
    };
    let mock = start_mock(MockFlirConfig::default(), faults, None);
    let mut ptu = open(&mock.path).await;
    let goal = Goal {
        pan_rad: -0.2,
        tilt_rad: 0.1,
        speed_rad_s: 1.0,
    };
    let end = ptu.move_and_track(goal, None, MOVE_TIMEOUT).await.unwrap();
    assert!((end.pan_rad + 0.2).abs() < 1e-3 && (end.tilt_rad - 0.1).abs() < 1e-3);
    assert!(ptu.stats().noise_lines >= 10, "{:?}", ptu.stats());
    mock.task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unplugged_unit_is_reported_and_reconnects_when_back() {
    let dir = std::env::temp_dir().join(format!("sqscan-flir-hil-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ptu");
    let mock = start_mock(MockFlirConfig::default(), Faults::default(), Some(&link));
    let mut ptu = open(&link).await;
    ptu.position().await.unwrap();
    mock.task.abort();
    let _ = mock.task.await;
    assert!(matches!(ptu.position().await, Err(Error::Disconnected)));

    let mut cfg = MockFlirConfig::default();
    cfg.tilt.initial_steps = 100;
    let faults = Faults {
        disconnect_after: Some(40),
        ..Faults::default()
    };
    let mock = start_mock(cfg, faults, Some(&link));
    ptu.reconnect().await.unwrap();
    assert_eq!(ptu.query_steps(Axis::Tilt, AxisQuery::Position).await.unwrap(), 100);
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
        Ok(ServeEnd::Unplugged { replies: 40 })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}
