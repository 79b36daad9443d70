//! The GigE Vision camera driver against aravis's camera emulator serving our mock line-profile
//! camera: the real GVCP/GVSP protocols on loopback, inside a private network namespace so that
//! no discovery or stream packet can leave the machine (`../shared/PROTOCOLS.md`). Each test
//! re-runs itself under `unshare -n` (root); where no namespace can be had it says so and skips.
#![cfg(feature = "gige")]

use std::time::{Duration, Instant};

use sqscan_drivers::Error;
use sqscan_drivers::gige::FeatureValue;
use sqscan_drivers::gige::camera::{GigeConfig, GigeSensor};
use sqscan_drivers::mock::gige::{CameraClock, FakeCameraConfig, FakeLineCamera, in_private_network};
use sqscan_drivers::sensor::ProfileSource;

/// What the mock camera sees: column `c` at sub-pixel row 50 + c / 4 (every tenth column from
/// the third on has no return), moving down one row a second.
fn scene(start: Instant) -> impl FnMut(Instant, &mut [f64]) + Send {
    move |t, rows| {
        let s = t.saturating_duration_since(start).as_secs_f64();
        for (c, r) in rows.iter_mut().enumerate() {
            *r = if c % 10 == 3 {
                f64::NAN
            } else {
                50.0 + c as f64 * 0.25 + s
            };
        }
    }
}

fn camera(clock: CameraClock) -> (FakeLineCamera, Instant) {
    let mut cfg = FakeCameraConfig::new("127.0.0.1", 64);
    cfg.rows_per_frame = 8;
    cfg.line_rate_hz = 200.0;
    cfg.clock = clock;
    let start = Instant::now();
    (FakeLineCamera::start(&cfg, Box::new(scene(start))).unwrap(), start)
}

fn config() -> GigeConfig {
    let mut c = GigeConfig::new("127.0.0.1");
    c.features = vec![
        ("DeviceScanType".into(), FeatureValue::Str("Linescan3D".into())),
        ("PixelFormat".into(), FeatureValue::Str("Coord3D_C16".into())),
        ("Scan3dCoordinateOffset".into(), FeatureValue::Float(10.0)),
    ];
    c.rows_per_frame = Some(8);
    c
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}

#[test]
fn opened_by_address_set_up_by_feature_name_and_decoded_row_by_row() {
    if !in_private_network("gige::opened_by_address_set_up_by_feature_name_and_decoded_row_by_row") {
        return;
    }
    let (_camera, start) = camera(CameraClock::default());
    runtime().block_on(async {
        let mut sensor = GigeSensor::open(config()).await.unwrap();
        let info = sensor.info().clone();
        assert_eq!((info.width, info.rows_per_frame), (64, 8), "{info:?}");
        assert_eq!(info.pixel_format, "Coord3D_C16");
        assert_eq!(info.encoding.scale, 1.0 / 16.0);
        assert_eq!(info.encoding.offset, 10.0);
        assert_eq!(info.encoding.invalid, Some(0.0));
        assert_eq!(info.line_rate_hz, 200.0);
        assert_eq!(info.serial, "SQ-LP-0001");
        sensor.start().await.unwrap();
        let mut got = Vec::new();
        while got.len() < 40 {
            got.push(sensor.next_profile(Duration::from_secs(5)).await.unwrap());
        }
        sensor.stop().await.unwrap();
        for w in got.windows(2) {
            assert_eq!(w[1].profile.seq, w[0].profile.seq.wrapping_add(1), "no profile lost");
            // One line period apart on the camera's clock, 5 ms, within the emulator's pacing.
            let dt = w[1].profile.timestamp_ns as f64 - w[0].profile.timestamp_ns as f64;
            assert!((dt - 5e6).abs() < 2e6, "rows {} ns apart", dt);
        }
        for p in &got {
            assert_eq!(p.profile.fraction_bits, 4);
            assert_eq!(p.profile.columns(), 64);
            // The row is 50 + c/4 + t, t the exposure since the scene's start: recover t from
            // column 0 (to the pixel's 1/16 row, 62.5 ms) and check every other column against it.
            let t = p.profile.row_px(0).unwrap() - 50.0;
            let host_t = p.received.duration_since(start).as_secs_f64();
            assert!(
                t >= 0.0 && t <= host_t + 0.032,
                "exposed at {t} s, received at {host_t} s"
            );
            for c in 0..64 {
                let px = p.profile.row_px(c);
                if c % 10 == 3 {
                    assert_eq!(px, None, "column {c} has no return");
                } else {
                    let want = 50.0 + c as f64 * 0.25 + t;
                    assert!((px.unwrap() - want).abs() <= 0.07, "column {c}: {px:?} against {want}");
                }
            }
        }
        assert_eq!(sensor.counts().dropped, 0);
    });
}

#[test]
fn features_that_cannot_be_set_are_named() {
    if !in_private_network("gige::features_that_cannot_be_set_are_named") {
        return;
    }
    let (_camera, _) = camera(CameraClock::default());
    runtime().block_on(async {
        for (name, value) in [
            ("NoSuchFeature", FeatureValue::Int(1)),
            ("DeviceScanType", FeatureValue::Str("Linescan9D".into())),
            ("PixelFormat", FeatureValue::Str("Mono8".into())),
            ("Width", FeatureValue::Int(100_000)),
        ] {
            let mut cfg = config();
            cfg.features.push((name.into(), value));
            let e = GigeSensor::open(cfg).await.err().unwrap();
            match &e {
                Error::Feature { feature, .. } => assert_eq!(feature, name, "{e}"),
                other => panic!("{name}: {other}"),
            }
        }
        // A camera that is not there is named by its address.
        let e = GigeSensor::open(GigeConfig::new("127.0.0.2")).await.err().unwrap();
        assert!(e.to_string().contains("127.0.0.2"), "{e}");
    });
}

#[test]
fn the_camera_clock_runs_with_its_offset_and_drift() {
    if !in_private_network("gige::the_camera_clock_runs_with_its_offset_and_drift") {
        return;
    }
    // 5000 s ahead and 2 % fast (far beyond a real camera's tens of ppm, so that three seconds
    // show it above the jitter of the blocks' arrival).
    let clock = CameraClock {
        offset_s: 5000.0,
        drift_ppm: 20_000.0,
    };
    let (_camera, _) = camera(clock);
    runtime().block_on(async {
        let mut sensor = GigeSensor::open(config()).await.unwrap();
        sensor.start().await.unwrap();
        let first = sensor.next_profile(Duration::from_secs(5)).await.unwrap();
        let mut last = first.clone();
        // Every profile's arrival and stamp, from the first one's.
        let mut samples = vec![(0.0, 0.0)];
        while last.received.duration_since(first.received) < Duration::from_millis(3000) {
            last = sensor.next_profile(Duration::from_secs(5)).await.unwrap();
            samples.push((
                last.received.duration_since(first.received).as_secs_f64(),
                (last.profile.timestamp_ns - first.profile.timestamp_ns) as f64 * 1e-9,
            ));
        }
        sensor.stop().await.unwrap();
        assert!(
            first.profile.timestamp_ns > 5_000_000_000_000 - 1,
            "{}",
            first.profile.timestamp_ns
        );
        // The camera counts 1.02 s for every second of the host's: the slope of the profiles'
        // stamps over their arrivals (each block arrives as its last row is exposed), fitted
        // over every arrival in the three seconds, so that one late arrival on a busy host (the
        // first one, say) does not tilt it. Within 1 %: no drift would be 2 % off.
        let n = samples.len() as f64;
        let (mx, my) = samples.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
        let (sxy, sxx) = samples.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
            (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
        });
        let rate = sxy / sxx;
        let camera_s = (last.profile.timestamp_ns - first.profile.timestamp_ns) as f64 * 1e-9;
        assert!(
            (rate - 1.02).abs() < 0.01,
            "rate {rate} over {} arrivals; camera {camera_s} s in host {} s",
            samples.len(),
            last.received.duration_since(first.received).as_secs_f64()
        );
        // And the rows are one line period apart on the host's clock.
        let rows = f64::from(last.profile.seq - first.profile.seq);
        assert!(
            (camera_s / 1.02 / rows - 0.005).abs() < 0.0002,
            "{camera_s} s for {rows} rows"
        );
    });
}

#[test]
fn a_camera_unplugged_while_acquiring_is_a_disconnect() {
    if !in_private_network("gige::a_camera_unplugged_while_acquiring_is_a_disconnect") {
        return;
    }
    let (camera, _) = camera(CameraClock::default());
    runtime().block_on(async {
        let mut sensor = GigeSensor::open(config()).await.unwrap();
        sensor.start().await.unwrap();
        for _ in 0..10 {
            sensor.next_profile(Duration::from_secs(5)).await.unwrap();
        }
        drop(camera);
        let t0 = Instant::now();
        let e = loop {
            match sensor.next_profile(Duration::from_secs(20)).await {
                Ok(_) => continue,
                Err(e) => break e,
            }
        };
        assert!(matches!(e, Error::Disconnected), "{e}");
        assert!(
            t0.elapsed() < Duration::from_secs(15),
            "noticed after {:?}",
            t0.elapsed()
        );
        // And it stays so.
        assert!(matches!(
            sensor.next_profile(Duration::from_secs(1)).await,
            Err(Error::Disconnected)
        ));
    });
}
