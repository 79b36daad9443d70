//! Sweep assembly: PTU position samples and laser profiles, taken while the unit moves, into one
//! organized range image and its point cloud in the base frame.
//!
//! [`assemble`] is pure and synchronous (samples and profiles in, a [`Sweep`] out), so it
//! is tested without devices; [`acquire::acquire`] drives a PTU and a profile sensor through one
//! sweep and hands what it collected to [`assemble`]. `docs/SWEEP.md` tells the same story for
//! people.
//!
//! # Clock mapping
//!
//! A profile carries the sensor's own exposure time (`timestamp_ns`, an unrelated clock) and the
//! host time its frame was received; position samples carry host time. A profile's delay
//! `received - exposure` is a fixed part (exposure-to-send latency inside the sensor, plus the
//! transmission of one frame) and a variable, never negative part (line buffering, frames that
//! complete in the same read, the host scheduler). So for every profile
//! `received_host - sensor_time >= offset + fixed`, with equality for a frame that saw no extra
//! delay, and the minimum of `received_host - sensor_time` over the sweep is the best estimate of
//! `offset + fixed`: over ~150 frames, at least one arrives promptly. A mean would be biased by
//! every late frame; the minimum is not biased by any of them. The part of the fixed latency
//! that happens before the frame starts moving (exposure to send), unknown to the host, is
//! [`SweepSettings::sensor_latency_s`] (default 0): exposure in host time is
//! `sensor_time + min(received_host - sensor_time) - sensor_latency_s`. This assumes the fixed
//! latency is constant and the sensor clock does not drift measurably against the host's during
//! one sweep (a few seconds: 50 ppm is 0.15 ms).
//!
//! # Joint angles
//!
//! Each profile is exposed at once, so it gets one pan and one tilt: linearly interpolated
//! between the two position samples that bracket its exposure (as ROS laser_assembler and tf
//! do). Never extrapolated: a profile outside the samples' span is dropped and counted.
//!
//! # What is dropped and counted
//!
//! In arrival order: a sequence number seen before is a duplicate; one behind the newest (a late
//! frame) is out of order; both are dropped (rows of the image stay in exposure order). Sequence
//! numbers between the first and the newest never received are missing. A profile whose column
//! count differs from the calibration's, or whose fixed-point encoding (fraction bits) differs,
//! is dropped. Then the never-extrapolate rule. `received` equals `kept` plus all `dropped_*`.

pub mod acquire;

use std::collections::HashSet;
use std::time::{Duration, Instant};

use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use sqscan_drivers::PositionSample;
use sqscan_drivers::sensor::ReceivedProfile;

use crate::calibration::Calibration;
use crate::cloud::{Field, FieldData, PointCloud};

pub use acquire::{acquire, acquire_live};

/// What happened to the profiles of one sweep.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default)]
pub struct SweepReport {
    /// Profiles handed to the assembler.
    pub received: usize,
    /// Profiles in the assembled sweep (rows of the image).
    pub kept: usize,
    /// Exposed outside the span of the position samples (never extrapolated).
    pub dropped_extrapolated: usize,
    /// A sequence number already received.
    pub dropped_duplicate: usize,
    /// A sequence number behind the newest received (a late frame).
    pub dropped_out_of_order: usize,
    /// Sequence numbers between the first and the newest that never arrived.
    pub missing_seq: usize,
    /// Column count differs from the calibration's.
    pub dropped_bad_columns: usize,
    /// Fixed-point encoding (fraction bits) differs from the calibration's.
    pub dropped_bad_encoding: usize,
    /// Position samples used.
    pub position_samples: usize,
    /// Points with a return.
    pub points: usize,
    /// Exposure time of the last kept profile after the first (s).
    pub duration_s: f64,
    /// Largest delay of a kept profile beyond the least-delayed one (s): how much the clock
    /// mapping corrected.
    pub max_extra_delay_s: f64,
    /// Where each profile's exposure time came from: `"profile"` (the sensor stamps every
    /// profile: SQPF), `"block_and_line_rate"` (a GigE Vision block's stamp plus the row's index
    /// over the line rate; line timestamps in chunk data are not read), empty where no sensor
    /// stamped it (simulated sweeps).
    pub profile_times: String,
}

/// One sweep: an organized range image, rows = profiles in exposure order, columns = sensor
/// columns, and its point cloud. The one sweep type: [`assemble`] makes it from what the devices
/// delivered, `sim::simulate` from a scene, and the daemon carries it.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// Profiles (rows).
    pub profiles: usize,
    pub columns: usize,
    /// Host time of the first profile's exposure (of the first position sample when no profile
    /// was kept) for a sweep taken with devices on this host; `None` for a simulated one, whose
    /// stamps are on no host's clock.
    pub start: Option<Instant>,
    /// Each profile's exposure time since the first profile's (s).
    pub stamp_s: Vec<f64>,
    /// Each profile's sequence number (the sensor's; the profile index for a simulated sweep).
    pub seq: Vec<u32>,
    /// Each profile's joint angles (rad): interpolated between position samples, or the
    /// simulated rig's exact ones.
    pub pan_rad: Vec<f64>,
    pub tilt_rad: Vec<f64>,
    /// Profile-major `profiles x columns`: distance from the sensor origin (m), NaN = no return.
    pub range_m: Vec<f32>,
    /// Organized cloud in the base frame (`width = columns`, `height = profiles`, NaN = no
    /// return), with the sensor pose at mid-sweep as viewpoint. An assembled sweep has an
    /// `intensity` (u8) field when every kept profile carried intensities; a simulated one has
    /// `intensity` and the ground truth `label` (u32, see `sim::LABEL_NONE`).
    pub cloud: PointCloud,
    /// What happened to the profiles.
    pub report: SweepReport,
}

impl Sweep {
    /// The smallest sweep there is: two profiles of three columns on a flat patch 0.86 m away,
    /// every pixel a return but `hole` (an index into the pixels). What the daemon's tests hand
    /// over where a sweep's content does not matter, only its passage.
    pub fn flat_patch(hole: Option<usize>) -> Sweep {
        let mut points = vec![[0.5f32, 0.0, 0.7]; 6];
        let mut range_m = vec![0.86f32; 6];
        if let Some(k) = hole.filter(|&k| k < points.len()) {
            points[k] = [f32::NAN; 3];
            range_m[k] = f32::NAN;
        }
        let returns = range_m.iter().filter(|r| r.is_finite()).count();
        Sweep {
            profiles: 2,
            columns: 3,
            start: None,
            stamp_s: vec![0.0, 0.02],
            seq: vec![0, 1],
            pan_rad: vec![0.0; 2],
            tilt_rad: vec![0.5, 0.51],
            range_m,
            cloud: PointCloud::organized(3, 2, points),
            report: SweepReport {
                received: 2,
                kept: 2,
                points: returns,
                ..SweepReport::default()
            },
        }
    }

    /// The sweep if it kept at least `needed` profiles, else [`SweepError::TooFewProfiles`].
    pub fn require_profiles(self, needed: usize) -> Result<Sweep, SweepError> {
        if self.profiles < needed {
            return Err(SweepError::TooFewProfiles {
                kept: self.profiles,
                needed,
                report: Box::new(self.report),
            });
        }
        Ok(self)
    }

    /// Points with a return.
    pub fn finite_points(&self) -> usize {
        self.range_m.iter().filter(|r| r.is_finite()).count()
    }
}

/// Why a sweep failed. A sweep cut short by a fault is always one of these, never a partial
/// [`Sweep`].
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// The pan-tilt unit failed (timeout, fault, unplugged, IO).
    #[error("PTU: {0}")]
    Ptu(#[source] sqscan_drivers::Error),
    /// The profile sensor failed (silent too long, unplugged, IO).
    #[error("profile sensor: {0}")]
    Sensor(#[source] sqscan_drivers::Error),
    /// The PTU reported the move ended without reaching the goal (halted by someone else).
    #[error("PTU stopped at tilt {tilt_rad:.4} rad, short of the sweep's end {goal_rad:.4} rad")]
    PtuStopped { tilt_rad: f64, goal_rad: f64 },
    /// Too few usable profiles.
    #[error("only {kept} usable profiles, {needed} needed ({report:?})")]
    TooFewProfiles {
        kept: usize,
        needed: usize,
        // Boxed: the report is large, and every sweep's `Result` would carry its size.
        report: Box<SweepReport>,
    },
    /// No position sample to take joint angles from.
    #[error("no PTU position samples: cannot place any profile")]
    NoPositionSamples,
    /// The settings make no sweep.
    #[error("sweep settings: {field}: {reason}")]
    Settings { field: &'static str, reason: String },
}

/// How to sweep. Deserialized from TOML/JSON with every field optional (defaults: the Fig. 3
/// rig's sweep); durations are in seconds (`timeout_s`, `grace_s`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepSettings {
    /// Pan during the sweep (rad).
    pub pan_rad: f64,
    /// Tilt at the start of the sweep (rad).
    pub tilt_from_rad: f64,
    /// Tilt at the end; smaller than `tilt_from_rad` sweeps back (rad).
    pub tilt_to_rad: f64,
    /// Tilt speed while sweeping (rad/s).
    pub speed_rad_s: f64,
    /// Speed of the move to the start (rad/s).
    pub approach_speed_rad_s: f64,
    /// Fewer kept profiles than this fail the sweep.
    pub min_profiles: usize,
    /// Slack beyond a move's nominal duration before it counts as stuck, and the longest the
    /// sensor may stay silent while acquiring.
    #[serde(rename = "timeout_s", with = "secs")]
    pub timeout: Duration,
    /// After the move has ended and the sensor was stopped, frames still on the line are read
    /// until the line has been quiet this long.
    #[serde(rename = "grace_s", with = "secs")]
    pub grace: Duration,
    /// The sensor's fixed latency from exposure to sending a frame (s), subtracted from the
    /// mapped exposure time (see the module docs).
    pub sensor_latency_s: f64,
}

impl Default for SweepSettings {
    fn default() -> Self {
        Self {
            pan_rad: 0.0,
            tilt_from_rad: 0.49,
            tilt_to_rad: 0.84,
            speed_rad_s: 0.12,
            approach_speed_rad_s: 0.5,
            min_profiles: 50,
            timeout: Duration::from_secs(10),
            grace: Duration::from_millis(200),
            sensor_latency_s: 0.0,
        }
    }
}

impl SweepSettings {
    /// The same sweep backwards (for continuous back-and-forth sweeping).
    pub fn reversed(&self) -> SweepSettings {
        SweepSettings {
            tilt_from_rad: self.tilt_to_rad,
            tilt_to_rad: self.tilt_from_rad,
            ..self.clone()
        }
    }

    /// Nominal duration of the sweep move (s).
    pub fn nominal_duration_s(&self) -> f64 {
        (self.tilt_to_rad - self.tilt_from_rad).abs() / self.speed_rad_s
    }

    /// Checks that the settings make a sweep: finite angles, positive speeds, a non-empty tilt
    /// range, a timeout in (0, 1 h], a grace period up to 1 h, a latency in [0, 1] s.
    pub fn validate(&self) -> Result<(), SweepError> {
        let bad = |field, reason: String| Err(SweepError::Settings { field, reason });
        for (field, v) in [
            ("pan_rad", self.pan_rad),
            ("tilt_from_rad", self.tilt_from_rad),
            ("tilt_to_rad", self.tilt_to_rad),
        ] {
            if !v.is_finite() {
                return bad(field, format!("{v} is not finite"));
            }
        }
        for (field, v) in [
            ("speed_rad_s", self.speed_rad_s),
            ("approach_speed_rad_s", self.approach_speed_rad_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("{v} rad/s must be finite and > 0"));
            }
        }
        if self.tilt_from_rad == self.tilt_to_rad {
            return bad("tilt_to_rad", "equals tilt_from_rad: nothing to sweep".into());
        }
        if self.min_profiles == 0 {
            return bad("min_profiles", "give at least 1".into());
        }
        // Bounded so that deadlines computed from them stay representable.
        if self.timeout.is_zero() || self.timeout > MAX_WAIT {
            return bad(
                "timeout_s",
                format!("{:?}: give (0, {}] s", self.timeout, MAX_WAIT.as_secs()),
            );
        }
        if self.grace > MAX_WAIT {
            return bad(
                "grace_s",
                format!("{:?}: give [0, {}] s", self.grace, MAX_WAIT.as_secs()),
            );
        }
        if !(self.sensor_latency_s.is_finite() && (0.0..=1.0).contains(&self.sensor_latency_s)) {
            return bad("sensor_latency_s", format!("{} s: give [0, 1]", self.sensor_latency_s));
        }
        Ok(())
    }
}

/// The longest timeout or grace period settings may give.
const MAX_WAIT: Duration = Duration::from_secs(3600);

/// Durations as seconds (f64) in files.
mod secs {
    use std::time::Duration;

    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(d.as_secs_f64())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
        let v = f64::deserialize(d)?;
        Duration::try_from_secs_f64(v)
            .map_err(|_| serde::de::Error::custom(format!("{v} s: give a finite, non-negative number of seconds")))
    }
}

/// Seconds from `origin` to `t` (negative before it).
fn secs_since(origin: Instant, t: Instant) -> f64 {
    match t.checked_duration_since(origin) {
        Some(d) => d.as_secs_f64(),
        None => -origin.duration_since(t).as_secs_f64(),
    }
}

/// `origin` plus `s` seconds (either sign); `origin` if that is not representable.
fn instant_at(origin: Instant, s: f64) -> Instant {
    let d = Duration::try_from_secs_f64(s.abs()).unwrap_or_default();
    if s >= 0.0 {
        origin.checked_add(d).unwrap_or(origin)
    } else {
        origin.checked_sub(d).unwrap_or(origin)
    }
}

/// Position samples as `(host s since origin, pan, tilt)`, sorted by time, non-finite dropped.
fn sample_track(origin: Instant, samples: &[PositionSample]) -> Vec<(f64, f64, f64)> {
    let mut track: Vec<(f64, f64, f64)> = samples
        .iter()
        .filter(|s| s.pan_rad.is_finite() && s.tilt_rad.is_finite())
        .map(|s| (secs_since(origin, s.t), s.pan_rad, s.tilt_rad))
        .collect();
    track.sort_by(|a, b| a.0.total_cmp(&b.0));
    track
}

/// Pan and tilt at host time `t`, linearly interpolated between the bracketing samples; `None`
/// outside the samples' span (never extrapolated).
fn interpolate(track: &[(f64, f64, f64)], t: f64) -> Option<(f64, f64)> {
    let (first, last) = (track.first()?, track.last()?);
    if !(t >= first.0 && t <= last.0) {
        return None;
    }
    // First sample later than t; t >= first.0 so i >= 1 unless every sample is at t.
    let i = track.partition_point(|s| s.0 <= t);
    if i == 0 || i >= track.len() {
        // t equals the last sample's time.
        return Some((last.1, last.2));
    }
    let (a, b) = (track[i - 1], track[i]);
    let dt = b.0 - a.0;
    let f = if dt > 0.0 { (t - a.0) / dt } else { 0.0 };
    Some((a.1 + f * (b.1 - a.1), a.2 + f * (b.2 - a.2)))
}

/// Assembles one sweep from position samples and profiles (in arrival order) with the
/// calibration chain. `sensor_latency_s` is the sensor's fixed exposure-to-send latency (see
/// the module docs). Errors only when there is no position sample; how many profiles are enough
/// is the caller's call (see [`acquire::acquire`]).
pub fn assemble(
    samples: &[PositionSample],
    profiles: &[ReceivedProfile],
    calib: &Calibration,
    sensor_latency_s: f64,
) -> Result<Sweep, SweepError> {
    let origin = samples.iter().map(|s| s.t).min().ok_or(SweepError::NoPositionSamples)?;
    let track = sample_track(origin, samples);
    if track.is_empty() {
        return Err(SweepError::NoPositionSamples);
    }
    let mut report = SweepReport {
        received: profiles.len(),
        position_samples: track.len(),
        ..SweepReport::default()
    };
    let in_order = in_sequence(profiles, &mut report);
    let usable = well_formed(in_order, calib, &mut report);
    // Clock offset: the least-delayed frame. Every received profile informs it (a late or
    // duplicate frame only has a larger delay, which cannot lower the minimum).
    let offset = profiles
        .iter()
        .map(|p| secs_since(origin, p.received) - sensor_s(p))
        .fold(f64::INFINITY, f64::min);
    // Exposure times and joint angles.
    let mut rows: Vec<Row> = Vec::with_capacity(usable.len());
    for p in usable {
        let t = sensor_s(p) + offset - sensor_latency_s;
        match interpolate(&track, t) {
            Some((pan, tilt)) => rows.push(Row { p, t, pan, tilt }),
            None => report.dropped_extrapolated += 1,
        }
    }
    let Projected {
        range_m,
        points,
        intensity,
    } = project(&rows, calib);
    let (columns, n) = (calib.columns, rows.len());
    let t0 = rows.first().map_or(0.0, |r| r.t);
    let stamp_s: Vec<f64> = rows.iter().map(|r| r.t - t0).collect();
    let seq: Vec<u32> = rows.iter().map(|r| r.p.profile.seq).collect();
    let pan_rad: Vec<f64> = rows.iter().map(|r| r.pan).collect();
    let tilt_rad: Vec<f64> = rows.iter().map(|r| r.tilt).collect();
    report.kept = n;
    report.points = range_m.iter().filter(|r| r.is_finite()).count();
    report.duration_s = stamp_s.last().copied().unwrap_or(0.0);
    report.max_extra_delay_s = rows
        .iter()
        .map(|r| secs_since(origin, r.p.received) - sensor_s(r.p) - offset)
        .fold(0.0f64, f64::max);
    let mut cloud = PointCloud::organized(columns, n, points);
    if let Some(intensity) = intensity {
        cloud.fields.push(Field::scalar("intensity", FieldData::U8(intensity)));
    }
    if n > 0 {
        let mid = n / 2;
        let pose = calib.sensor_in_base(pan_rad[mid], tilt_rad[mid]);
        let (t, q) = (pose.translation.vector, pose.rotation.quaternion());
        cloud.viewpoint = Some([t.x, t.y, t.z, q.w, q.i, q.j, q.k]);
    }
    let start = if n > 0 { instant_at(origin, t0) } else { origin };
    Ok(Sweep {
        profiles: n,
        columns,
        start: Some(start),
        stamp_s,
        seq,
        pan_rad,
        tilt_rad,
        range_m,
        cloud,
        report,
    })
}

/// The sensor's timestamp of a profile (s).
fn sensor_s(p: &ReceivedProfile) -> f64 {
    p.profile.timestamp_ns as f64 * 1e-9
}

/// The profiles in sequence: duplicates and late frames dropped and counted, sequence numbers
/// unwrapped to u64 relative to the newest, and the ones that never arrived counted.
fn in_sequence<'a>(profiles: &'a [ReceivedProfile], report: &mut SweepReport) -> Vec<&'a ReceivedProfile> {
    let mut seen: HashSet<u64> = HashSet::new();
    let mut newest: Option<(u32, u64)> = None;
    let mut first_seq = 0u64;
    let mut in_order: Vec<&ReceivedProfile> = Vec::with_capacity(profiles.len());
    for p in profiles {
        let seq = p.profile.seq;
        let unwrapped = match newest {
            None => {
                first_seq = 1 << 32;
                1 << 32
            }
            Some((raw, u)) => u.wrapping_add_signed(i64::from(seq.wrapping_sub(raw) as i32)),
        };
        if !seen.insert(unwrapped) {
            report.dropped_duplicate += 1;
            continue;
        }
        if newest.is_some_and(|(_, u)| unwrapped < u) {
            report.dropped_out_of_order += 1;
            continue;
        }
        newest = Some((seq, unwrapped));
        in_order.push(p);
    }
    if let Some((_, last)) = newest {
        // Everything between the first and the newest that never arrived (late frames did).
        let span = last.saturating_sub(first_seq) + 1;
        let arrived = seen.iter().filter(|&&u| u >= first_seq && u <= last).count() as u64;
        report.missing_seq = usize::try_from(span.saturating_sub(arrived)).unwrap_or(usize::MAX);
    }
    in_order
}

/// The profiles of the calibration's width and encoding; the others dropped and counted.
fn well_formed<'a>(
    in_order: Vec<&'a ReceivedProfile>,
    calib: &Calibration,
    report: &mut SweepReport,
) -> Vec<&'a ReceivedProfile> {
    let mut usable = Vec::with_capacity(in_order.len());
    for p in in_order {
        if p.profile.rows.len() != calib.columns {
            report.dropped_bad_columns += 1;
        } else if p.profile.fraction_bits != calib.fraction_bits {
            report.dropped_bad_encoding += 1;
        } else {
            usable.push(p);
        }
    }
    usable
}

/// A profile of the sweep, with its exposure time (s since the first position sample) and the
/// joint angles then.
struct Row<'a> {
    p: &'a ReceivedProfile,
    t: f64,
    pan: f64,
    tilt: f64,
}

/// The sweep's pixels, a row a profile: range, point in the base frame, and intensity where
/// every profile has one.
struct Projected {
    range_m: Vec<f32>,
    points: Vec<[f32; 3]>,
    intensity: Option<Vec<u8>>,
}

/// Every pixel through the calibration chain at its profile's joint angles.
fn project(rows: &[Row], calib: &Calibration) -> Projected {
    let (columns, n) = (calib.columns, rows.len());
    let mut range_m = vec![f32::NAN; n * columns];
    let mut points = vec![[f32::NAN; 3]; n * columns];
    let with_intensity = n > 0
        && rows
            .iter()
            .all(|r| r.p.profile.intensity.as_ref().is_some_and(|i| i.len() == columns));
    let mut intensity = if with_intensity {
        vec![0u8; n * columns]
    } else {
        Vec::new()
    };
    for (i, r) in rows.iter().enumerate() {
        let pose = calib.sensor_in_base(r.pan, r.tilt);
        for (col, &raw) in r.p.profile.rows.iter().enumerate() {
            let Some(q) = calib.point_in_sensor(col, raw) else {
                continue;
            };
            let k = i * columns + col;
            range_m[k] = q.norm() as f32;
            let b = pose.transform_point(&Point3::from(q));
            points[k] = [b.x as f32, b.y as f32, b.z as f32];
            if let (Some(dst), Some(src)) = (
                intensity.get_mut(k),
                r.p.profile.intensity.as_ref().and_then(|v| v.get(col)),
            ) {
                *dst = *src;
            }
        }
    }
    Projected {
        range_m,
        points,
        intensity: with_intensity.then_some(intensity),
    }
}

#[cfg(test)]
mod tests;
