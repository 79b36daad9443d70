//! Hardware-in-the-loop tests: the real profile sensor device against the mock sensor over real
//! pseudo-terminals. No sleeps: every wait is "until a condition, with a deadline".

use std::time::{Duration, Instant};

use sqscan_drivers::Error;
use sqscan_drivers::mock::{Faults, MockPort, ServeEnd};
use sqscan_drivers::profile::{Profile, SeqEvent};
use sqscan_drivers::sensor::{ProfileSensor, SensorConfig};

const WAIT: Duration = Duration::from_secs(10);
const COLUMNS: usize = 64;

/// A synthetic sensor: column c reports row 10 + c px (4 fraction bits), every 8th no return.
fn ramp(_now: Instant) -> Profile {
    Profile {
        seq: 0,
        timestamp_ns: 0,
        fraction_bits: 4,
        rows: (0..COLUMNS)
            .map(|c| if c % 8 == 7 { 0 } else { (16 * (10 + c)) as u16 })
            .collect(),
        intensity: Some(vec![200; COLUMNS]),
    }
}

fn start_mock(faults: Faults) -> (std::path::PathBuf, tokio::task::JoinHandle<std::io::Result<ServeEnd>>) {
    let port = MockPort::create(None).expect("a pty");
    let path = port.path().to_owned();
    let task = tokio::spawn(port.stream(ramp, Duration::from_millis(10), faults));
    (path, task)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn profiles_stream_between_start_and_stop() {
    let (path, task) = start_mock(Faults::default());
    let mut sensor = ProfileSensor::open(&path, SensorConfig::default()).unwrap();
    // Nothing comes before START.
    assert!(matches!(
        sensor.next_profile(Duration::from_millis(300)).await,
        Err(Error::Timeout { .. })
    ));
    sensor.start().await.unwrap();
    let mut last_ts = None;
    for i in 0..20 {
        let r = sensor.next_profile(WAIT).await.unwrap();
        assert_eq!(r.profile.seq, i);
        assert_eq!(r.seq, if i == 0 { SeqEvent::First } else { SeqEvent::InOrder });
        assert_eq!(r.profile.row_px(3), Some(13.0));
        assert_eq!(r.profile.row_px(7), None);
        if let Some(t) = last_ts {
            assert!(r.profile.timestamp_ns > t, "the sensor clock runs forward");
        }
        last_ts = Some(r.profile.timestamp_ns);
    }
    sensor.stop().await.unwrap();
    // Frames already on the line drain; then the stream is quiet.
    let quiet = loop {
        match sensor.next_profile(Duration::from_millis(500)).await {
            Ok(r) => assert!(r.profile.seq < 1000, "still streaming after STOP"),
            Err(e) => break e,
        }
    };
    assert!(matches!(quiet, Error::Timeout { .. }), "{quiet}");
    // START again: sequence numbers continue.
    sensor.start().await.unwrap();
    let r = sensor.next_profile(WAIT).await.unwrap();
    assert!(matches!(r.seq, SeqEvent::InOrder), "{:?}", r.seq);
    assert_eq!(sensor.counts().dropped, 0);
    task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn drops_corruption_and_garbage_are_counted_and_survived() {
    let faults = Faults {
        drop_every: 5,
        corrupt_every: 7,
        garbage_every: 3,
        seed: 11,
        ..Faults::default()
    };
    let (path, task) = start_mock(faults);
    let mut sensor = ProfileSensor::open(&path, SensorConfig::default()).unwrap();
    sensor.start().await.unwrap();
    let mut good = 0;
    while good < 40 {
        let r = sensor.next_profile(WAIT).await.unwrap();
        assert_eq!(r.profile.rows.len(), COLUMNS);
        good += 1;
    }
    let counts = sensor.counts();
    // Of ~50 frames, every 5th dropped and every 7th corrupted (each a gap for the host).
    assert!(counts.dropped >= 10, "{counts:?}");
    assert!(sensor.frame_errors() >= 4, "{}", sensor.frame_errors());
    assert!(sensor.decoder_stats().skipped_bytes > 0);
    assert_eq!(counts.duplicates + counts.restarts, 0, "{counts:?}");
    task.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unplugged_sensor_is_reported() {
    let faults = Faults {
        disconnect_after: Some(5),
        ..Faults::default()
    };
    let (path, task) = start_mock(faults);
    let mut sensor = ProfileSensor::open(&path, SensorConfig::default()).unwrap();
    sensor.start().await.unwrap();
    let err = loop {
        match sensor.next_profile(WAIT).await {
            Ok(r) => assert!(r.profile.seq < 5),
            Err(e) => break e,
        }
    };
    assert!(matches!(err, Error::Disconnected), "{err}");
    assert!(matches!(task.await.unwrap(), Ok(ServeEnd::Unplugged { replies: 5 })));
}
