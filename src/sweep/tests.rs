use std::path::PathBuf;
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sqscan_drivers::PositionSample;
use sqscan_drivers::profile::{Profile, SeqEvent};
use sqscan_drivers::sensor::ReceivedProfile;

use super::*;

fn calib() -> Calibration {
    Calibration::from_file(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("calibration/sim_rig.toml")).unwrap()
}

/// The sensor clock reads this much more than host seconds since `t0` (an unrelated clock).
const SENSOR_AHEAD_S: f64 = 1234.5;

struct Rig {
    t0: Instant,
    columns: usize,
}

impl Rig {
    fn new() -> Rig {
        Rig {
            t0: Instant::now(),
            columns: calib().columns,
        }
    }

    fn at(&self, s: f64) -> Instant {
        self.t0 + Duration::from_secs_f64(s)
    }

    fn sample(&self, s: f64, pan: f64, tilt: f64) -> PositionSample {
        PositionSample {
            t: self.at(s),
            span: Duration::from_millis(10),
            pan_rad: pan,
            tilt_rad: tilt,
        }
    }

    /// A profile exposed at host second `exposed`, received `delay` later; rows vary by column
    /// (every 7th column without a return).
    fn profile(&self, seq: u32, exposed: f64, delay: f64) -> ReceivedProfile {
        let rows = (0..self.columns)
            .map(|c| if c % 7 == 3 { 0 } else { 1000 + 5 * c as u16 })
            .collect();
        ReceivedProfile {
            profile: Profile {
                seq,
                timestamp_ns: ((exposed + SENSOR_AHEAD_S) * 1e9).round() as u64,
                fraction_bits: 4,
                rows,
                intensity: Some(vec![9; self.columns]),
            },
            received: self.at(exposed + delay),
            seq: SeqEvent::InOrder,
        }
    }
}

fn dropped(r: &SweepReport) -> usize {
    r.dropped_extrapolated
        + r.dropped_duplicate
        + r.dropped_out_of_order
        + r.dropped_bad_columns
        + r.dropped_bad_encoding
}

/// Every point is the calibration chain at the sweep's angles, every range the sensor-frame
/// distance, the cloud organized.
fn check_points(s: &Sweep, profiles: &[&ReceivedProfile], cal: &Calibration) {
    assert_eq!(s.cloud.width, s.columns);
    assert_eq!(s.cloud.height, s.profiles);
    assert_eq!(s.range_m.len(), s.profiles * s.columns);
    for (i, p) in profiles.iter().enumerate() {
        for (col, &raw) in p.profile.rows.iter().enumerate() {
            let k = i * s.columns + col;
            match cal.point_in_base(col, raw, s.pan_rad[i], s.tilt_rad[i]) {
                None => {
                    assert!(s.range_m[k].is_nan());
                    assert!(s.cloud.points[k].iter().all(|c| c.is_nan()));
                }
                Some(q) => {
                    let got = s.cloud.points[k];
                    for (a, b) in got.iter().zip([q.x, q.y, q.z]) {
                        assert!((f64::from(*a) - b).abs() < 1e-5, "row {i} col {col}: {got:?} vs {q}");
                    }
                    let r = cal.point_in_sensor(col, raw).unwrap().norm();
                    assert!((f64::from(s.range_m[k]) - r).abs() < 1e-5);
                }
            }
        }
    }
    assert_eq!(s.report.points, s.range_m.iter().filter(|r| r.is_finite()).count());
    assert!(s.report.points > 0);
}

#[test]
fn joint_angles_are_interpolated_between_the_bracketing_samples() {
    let rig = Rig::new();
    let cal = calib();
    let samples = [
        rig.sample(0.0, 0.10, 0.5),
        rig.sample(0.1, 0.10, 0.6),
        rig.sample(0.2, 0.12, 0.8),
    ];
    // Delays 2 ms (the least), 9 ms, 4 ms: the 2 ms is the fixed latency given.
    let profiles = [
        rig.profile(0, 0.05, 0.002),
        rig.profile(1, 0.15, 0.009),
        rig.profile(2, 0.2, 0.004),
    ];
    let s = assemble(&samples, &profiles, &cal, 0.002).unwrap();
    assert_eq!(s.profiles, 3);
    for (got, want) in s.tilt_rad.iter().zip([0.55, 0.7, 0.8]) {
        assert!((got - want).abs() < 1e-6, "tilt {got} vs {want}");
    }
    for (got, want) in s.pan_rad.iter().zip([0.10, 0.11, 0.12]) {
        assert!((got - want).abs() < 1e-6, "pan {got} vs {want}");
    }
    for (got, want) in s.stamp_s.iter().zip([0.0, 0.1, 0.15]) {
        assert!((got - want).abs() < 1e-6, "stamp {got} vs {want}");
    }
    assert_eq!(s.seq, [0, 1, 2]);
    assert!((secs_since(rig.t0, s.start.unwrap()) - 0.05).abs() < 1e-6);
    assert!((s.report.duration_s - 0.15).abs() < 1e-6);
    assert!((s.report.max_extra_delay_s - 0.007).abs() < 1e-6);
    assert_eq!(s.report.position_samples, 3);
    check_points(&s, &profiles.iter().collect::<Vec<_>>(), &cal);
    let intensity = s.cloud.field("intensity").expect("intensity carried");
    assert_eq!(intensity.data.len(), 3 * cal.columns);
    assert!(s.cloud.viewpoint.is_some());

    // Without the latency the exposures map 2 ms late: the tilt follows.
    let late = assemble(&samples, &profiles, &cal, 0.0).unwrap();
    assert!((late.tilt_rad[0] - 0.552).abs() < 1e-6, "{}", late.tilt_rad[0]);
}

#[test]
fn profiles_outside_the_samples_are_dropped_never_extrapolated() {
    let rig = Rig::new();
    let cal = calib();
    let samples = [rig.sample(0.1, 0.0, 0.5), rig.sample(0.3, 0.0, 0.7)];
    let profiles = [
        rig.profile(0, 0.05, 0.001),   // before the first sample
        rig.profile(1, 0.1001, 0.001), // just after it
        rig.profile(2, 0.2, 0.001),
        rig.profile(3, 0.2999, 0.001), // just before the last
        rig.profile(4, 0.31, 0.001),   // after it
    ];
    let s = assemble(&samples, &profiles, &cal, 0.001).unwrap();
    assert_eq!(s.report.dropped_extrapolated, 2);
    assert_eq!(s.seq, [1, 2, 3]);
    for (got, want) in s.tilt_rad.iter().zip([0.5001, 0.6, 0.6999]) {
        assert!((got - want).abs() < 1e-6, "tilt {got} vs {want}");
    }
    assert_eq!(s.report.received, 5);
    assert_eq!(s.report.kept + dropped(&s.report), 5);

    // One sample brackets nothing (but its own instant).
    let s = assemble(&samples[..1], &profiles, &cal, 0.001).unwrap();
    assert_eq!((s.profiles, s.report.dropped_extrapolated), (0, 5));
    assert_eq!(s.cloud.height, 0);
    assert_eq!(s.start, Some(samples[0].t));

    // No samples at all is an error, not an empty sweep.
    assert!(matches!(
        assemble(&[], &profiles, &cal, 0.001),
        Err(SweepError::NoPositionSamples)
    ));
    let nan = [rig.sample(0.1, f64::NAN, 0.5)];
    assert!(matches!(
        assemble(&nan, &profiles, &cal, 0.001),
        Err(SweepError::NoPositionSamples)
    ));
}

#[test]
fn duplicates_late_frames_and_gaps_are_counted() {
    let rig = Rig::new();
    let cal = calib();
    let samples = [rig.sample(0.0, 0.0, 0.5), rig.sample(1.0, 0.0, 0.6)];
    // Arrival order: 10, 11, 11 (duplicate), 13 (12 missing so far), 12 (late), 12 (duplicate
    // of the late one), 15 (14 missing for good).
    let arrivals = [
        (10, 0.1),
        (11, 0.2),
        (11, 0.2),
        (13, 0.4),
        (12, 0.3),
        (12, 0.3),
        (15, 0.6),
    ];
    let profiles: Vec<ReceivedProfile> = arrivals.iter().map(|&(seq, t)| rig.profile(seq, t, 0.001)).collect();
    let s = assemble(&samples, &profiles, &cal, 0.0).unwrap();
    let r = &s.report;
    assert_eq!(s.seq, [10, 11, 13, 15]);
    assert_eq!(
        (r.dropped_duplicate, r.dropped_out_of_order, r.missing_seq),
        (2, 1, 1),
        "{r:?}"
    );
    assert_eq!(r.kept + dropped(r), r.received);
    assert!(s.stamp_s.windows(2).all(|w| w[1] > w[0]), "rows in exposure order");
    check_points(&s, &[&profiles[0], &profiles[1], &profiles[3], &profiles[6]], &cal);

    // Sequence numbers wrap without a gap.
    let wrap: Vec<ReceivedProfile> = [u32::MAX - 1, u32::MAX, 0, 2]
        .iter()
        .enumerate()
        .map(|(i, &seq)| rig.profile(seq, 0.1 * (i + 1) as f64, 0.001))
        .collect();
    let s = assemble(&samples, &wrap, &cal, 0.0).unwrap();
    assert_eq!(s.profiles, 4);
    assert_eq!(
        (s.report.dropped_out_of_order, s.report.missing_seq),
        (0, 1),
        "{:?}",
        s.report
    );
}

#[test]
fn profiles_that_do_not_fit_the_calibration_are_dropped() {
    let rig = Rig::new();
    let cal = calib();
    let samples = [rig.sample(0.0, 0.0, 0.5), rig.sample(1.0, 0.0, 0.6)];
    let mut profiles: Vec<ReceivedProfile> = (0..4)
        .map(|i| rig.profile(i, 0.1 + 0.1 * f64::from(i), 0.001))
        .collect();
    profiles[1].profile.rows.pop();
    profiles[2].profile.fraction_bits = 5;
    profiles[3].profile.intensity = None;
    let s = assemble(&samples, &profiles, &cal, 0.0).unwrap();
    assert_eq!(s.seq, [0, 3]);
    assert_eq!((s.report.dropped_bad_columns, s.report.dropped_bad_encoding), (1, 1));
    assert_eq!(s.report.missing_seq, 0);
    // One kept profile without intensities: no intensity field rather than made-up values.
    assert!(s.cloud.field("intensity").is_none());
    check_points(&s, &[&profiles[0], &profiles[3]], &cal);
}

#[test]
fn the_clock_offset_comes_from_the_least_delayed_frame_despite_jitter() {
    let rig = Rig::new();
    let cal = calib();
    // A 0.35 rad sweep at 0.12 rad/s sampled at 50 Hz, profiles at 50 Hz offset by 7 ms.
    let speed = 0.12;
    let tilt_at = |t: f64| 0.49 + speed * t;
    let samples: Vec<PositionSample> = (0..=146)
        .map(|i| {
            let t = 0.02 * f64::from(i);
            rig.sample(t, 0.0, tilt_at(t))
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    // Delays: 3 ms fixed plus 0-25 ms of jitter, some frames bunched by a slow read.
    let profiles: Vec<ReceivedProfile> = (0..145u32)
        .map(|i| {
            let t = 0.007 + 0.02 * f64::from(i);
            let jitter = if i % 10 == 5 {
                0.04
            } else {
                rng.random_range(0.0..0.025)
            };
            rig.profile(i, t, 0.003 + jitter)
        })
        .collect();
    let s = assemble(&samples, &profiles, &cal, 0.003).unwrap();
    assert_eq!(s.profiles, 145, "{:?}", s.report);
    let min_jitter = profiles
        .iter()
        .map(|p| secs_since(rig.t0, p.received) - (p.profile.timestamp_ns as f64 * 1e-9 - SENSOR_AHEAD_S) - 0.003)
        .fold(f64::INFINITY, f64::min);
    for (i, tilt) in s.tilt_rad.iter().enumerate() {
        let want = tilt_at(0.007 + 0.02 * i as f64);
        // Off by no more than the least jitter (tenths of a millisecond) times the speed.
        assert!(
            (tilt - want).abs() <= speed * min_jitter + 1e-9,
            "profile {i}: tilt {tilt} vs {want}"
        );
        assert!(
            (tilt - want).abs() < speed * 0.001,
            "profile {i}: tilt {tilt} vs {want}"
        );
    }
    // Stamps follow the sensor clock, not the jittered arrival.
    for (i, st) in s.stamp_s.iter().enumerate() {
        assert!((st - 0.02 * i as f64).abs() < 1e-6, "stamp {i}: {st}");
    }
    // Mapping by arrival time instead would be off by up to 40 ms (5 mrad): the test can tell.
    assert!(s.report.max_extra_delay_s > 0.035);
}

#[test]
fn a_sweep_with_decreasing_tilt_assembles_in_exposure_order() {
    let rig = Rig::new();
    let cal = calib();
    let samples: Vec<PositionSample> = (0..=10)
        .map(|i| {
            let t = 0.1 * f64::from(i);
            rig.sample(t, -0.05, 0.84 - 0.12 * t)
        })
        .collect();
    let profiles: Vec<ReceivedProfile> = (0..20u32)
        .map(|i| rig.profile(100 + i, 0.025 + 0.05 * f64::from(i), 0.002))
        .collect();
    let s = assemble(&samples, &profiles, &cal, 0.002).unwrap();
    assert_eq!(s.profiles, 20);
    assert!(s.tilt_rad.windows(2).all(|w| w[1] < w[0]), "tilt decreases");
    for (i, tilt) in s.tilt_rad.iter().enumerate() {
        let want = 0.84 - 0.12 * (0.025 + 0.05 * i as f64);
        assert!((tilt - want).abs() < 1e-6, "profile {i}: {tilt} vs {want}");
    }
    assert!(s.pan_rad.iter().all(|p| (p + 0.05).abs() < 1e-12));
    check_points(&s, &profiles.iter().collect::<Vec<_>>(), &cal);
}

#[test]
fn too_few_profiles_is_an_error_with_the_report() {
    let rig = Rig::new();
    let cal = calib();
    let samples = [rig.sample(0.0, 0.0, 0.5), rig.sample(1.0, 0.0, 0.6)];
    let profiles = [
        rig.profile(0, 0.5, 0.001),
        rig.profile(0, 0.5, 0.001),
        rig.profile(1, 2.0, 0.001),
    ];
    let s = assemble(&samples, &profiles, &cal, 0.001).unwrap();
    let e = s.clone().require_profiles(2).unwrap_err();
    match &e {
        SweepError::TooFewProfiles { kept, needed, report } => {
            assert_eq!((*kept, *needed), (1, 2));
            assert_eq!((report.dropped_duplicate, report.dropped_extrapolated), (1, 1));
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("only 1 usable profiles, 2 needed"), "{e}");
    assert_eq!(s.require_profiles(1).unwrap().profiles, 1);
}

#[test]
fn settings_default_validate_and_read_from_toml() {
    let d = SweepSettings::default();
    d.validate().unwrap();
    let r = d.reversed();
    assert_eq!((r.tilt_from_rad, r.tilt_to_rad), (d.tilt_to_rad, d.tilt_from_rad));
    r.validate().unwrap();
    assert!((d.nominal_duration_s() - 0.35 / 0.12).abs() < 1e-9);

    let s: SweepSettings = toml::from_str("tilt_from_rad = 0.8\ntilt_to_rad = 0.5\ntimeout_s = 2.5\n").unwrap();
    assert_eq!(s.timeout, Duration::from_millis(2500));
    assert_eq!(s.speed_rad_s, d.speed_rad_s);
    s.validate().unwrap();
    assert!(toml::from_str::<SweepSettings>("timeout_s = -1.0").is_err());
    assert!(
        toml::from_str::<SweepSettings>("speed = 1.0").is_err(),
        "unknown fields refused"
    );

    for (bad, field) in [
        (
            SweepSettings {
                speed_rad_s: 0.0,
                ..d.clone()
            },
            "speed_rad_s",
        ),
        (
            SweepSettings {
                tilt_to_rad: f64::NAN,
                ..d.clone()
            },
            "tilt_to_rad",
        ),
        (
            SweepSettings {
                tilt_to_rad: d.tilt_from_rad,
                ..d.clone()
            },
            "tilt_to_rad",
        ),
        (
            SweepSettings {
                sensor_latency_s: -0.1,
                ..d.clone()
            },
            "sensor_latency_s",
        ),
        (
            SweepSettings {
                timeout: Duration::from_secs(1 << 40),
                ..d.clone()
            },
            "timeout_s",
        ),
        (
            SweepSettings {
                min_profiles: 0,
                ..d.clone()
            },
            "min_profiles",
        ),
    ] {
        let e = bad.validate().unwrap_err();
        assert!(matches!(e, SweepError::Settings { field: f, .. } if f == field), "{e}");
    }
}

#[test]
fn the_report_serializes() {
    let r = SweepReport {
        received: 3,
        kept: 2,
        dropped_duplicate: 1,
        ..SweepReport::default()
    };
    let json = serde_json::to_string(&r).unwrap();
    assert!(json.contains("\"dropped_duplicate\":1"), "{json}");
    assert!(json.contains("\"missing_seq\":0"), "{json}");
}

/// A GigE Vision camera's profiles: blocks of 10 rows, every row of a block received 2 ms after
/// the block's last row was exposed, stamped on a camera clock `ahead` seconds ahead of the
/// host's and `drift_ppm` fast.
fn camera_sweep(rig: &Rig, ahead: f64, drift_ppm: f64) -> Vec<ReceivedProfile> {
    (0..150u32)
        .map(|i| {
            let exposed = 0.1 + f64::from(i) / 50.0;
            let block_end = 0.1 + f64::from(i / 10 * 10 + 9) / 50.0;
            let mut p = rig.profile(i, exposed, block_end - exposed + 0.002);
            p.profile.timestamp_ns = ((exposed * (1.0 + drift_ppm * 1e-6) + ahead) * 1e9).round() as u64;
            p
        })
        .collect()
}

#[test]
fn a_camera_clock_ahead_and_drifting_assembles_the_same_sweep() {
    let rig = Rig::new();
    let cal = calib();
    // The tilt sweeps 0.5 -> 0.86 rad in 3.1 s, sampled every 10 ms.
    let samples: Vec<PositionSample> = (0..=310)
        .map(|k| {
            let t = f64::from(k) * 0.01;
            rig.sample(t, 0.0, 0.5 + 0.12 * t)
        })
        .collect();
    let reference = assemble(&samples, &camera_sweep(&rig, 0.0, 0.0), &cal, 0.0).unwrap();
    assert_eq!(reference.profiles, 150);
    for (ahead, drift) in [(86_400.0, 0.0), (5.0e4, 100.0), (1.0, -100.0)] {
        let s = assemble(&samples, &camera_sweep(&rig, ahead, drift), &cal, 0.0).unwrap();
        assert_eq!(s.profiles, 150);
        // 100 ppm over the 3 s sweep is 0.3 ms at most: 36 urad of tilt at 0.12 rad/s.
        let worst = s
            .tilt_rad
            .iter()
            .zip(&reference.tilt_rad)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 5e-5, "{ahead} s ahead, {drift} ppm: tilt off by {worst} rad");
        let moved = s
            .cloud
            .points
            .iter()
            .zip(&reference.cloud.points)
            .filter(|(a, _)| a[0].is_finite())
            .map(|(a, b)| (0..3).map(|k| f64::from(a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        assert!(moved < 1e-4, "{ahead} s ahead, {drift} ppm: a point moved {moved} m");
    }
}
