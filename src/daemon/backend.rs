//! What the daemon needs of a scanner, and the types a scanner hands it: the bottom of the
//! daemon's modules, which the backends (simulator, hardware), the acquisition loop and the
//! shared state all use and which uses none of them.
//!
//! A new way of getting sweeps (a replay of recorded sweeps, another rig) implements
//! [`Backend`] and is handed to [`Daemon::serve`](super::Daemon::serve); nothing else in the
//! daemon changes.

use std::future::Future;
use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime};

use super::reply::{DeviceJson, DeviceState};

use crate::sweep::Sweep;

/// A scanner the daemon drives: one sweep at a time, from the acquisition task.
pub trait Backend: Send + 'static {
    /// What `status` calls it: `"sim"`, `"hardware"`, ...
    fn name(&self) -> &'static str;

    /// Its devices as `status` shows them before the first sweep.
    fn devices(&self) -> Vec<DeviceStatus>;

    /// One sweep, from the configured start to the end (`forward`) or back. Device opens and
    /// failures along the way are noted on `devices`. A failed sweep is dropped and counted by
    /// the caller, which asks again; a backend that must wait before retrying (a device's
    /// backoff) waits in here.
    ///
    /// The joint angles go to `joints` as the sweep goes: every position sample a PTU gives
    /// (hardware), each profile's angles at its time (the simulator), or a recorded sweep's all
    /// at once (a replay).
    fn sweep(
        &mut self,
        forward: bool,
        devices: &Devices,
        joints: &JointFeed,
    ) -> impl Future<Output = Result<Swept, SweepFailure>> + Send;

    /// Leaves the devices quiet; bounded in time (the daemon is stopping).
    fn stop(&mut self) -> impl Future<Output = ()> + Send;

    /// Where the PTU and the sensor are mounted (published on ROS 2's `/tf_static`); `None` for
    /// a backend that knows no rig (a replay).
    fn mount(&self) -> Option<Mount> {
        None
    }
}

/// The PTU's joint angles at one moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSample {
    /// Unix time (s).
    pub unix_s: f64,
    pub pan_rad: f64,
    pub tilt_rad: f64,
}

/// Where a backend sends the joint angles as it learns them during a sweep, for whoever
/// publishes them live (ROS 2's joint states and `/tf`). Sending never waits: a follower that
/// falls more than [`JointFeed::CAPACITY`] samples behind loses the oldest and is told so.
#[derive(Debug, Clone)]
pub struct JointFeed(tokio::sync::broadcast::Sender<JointSample>);

impl Default for JointFeed {
    fn default() -> Self {
        JointFeed(tokio::sync::broadcast::channel(Self::CAPACITY).0)
    }
}

impl JointFeed {
    /// Samples held for a follower: several sweeps' worth at a PTU's 50 Hz or a profile rate.
    pub const CAPACITY: usize = 4096;

    /// The angles at host time `t`. Non-finite angles (a sample the assembler would not use
    /// either) are not sent.
    pub fn send(&self, t: Instant, pan_rad: f64, tilt_rad: f64) {
        if !(pan_rad.is_finite() && tilt_rad.is_finite()) || self.0.receiver_count() == 0 {
            return;
        }
        let _ = self.0.send(JointSample {
            unix_s: unix_s_of(t),
            pan_rad,
            tilt_rad,
        });
    }

    /// Every profile's angles of a sweep whose last profile was exposed at `last_profile`, in
    /// time order: each at `last_profile` less its time before the last profile, as the
    /// published sweep stamps its profiles.
    pub fn send_profiles(&self, sweep: &Sweep, last_profile: Instant) {
        let last_stamp = sweep.stamp_s.last().copied().unwrap_or(0.0);
        for (i, (pan, tilt)) in sweep.pan_rad.iter().zip(&sweep.tilt_rad).enumerate() {
            let before = (last_stamp - sweep.stamp_s.get(i).copied().unwrap_or(last_stamp)).max(0.0);
            let t = Duration::try_from_secs_f64(before)
                .ok()
                .and_then(|d| last_profile.checked_sub(d))
                .unwrap_or(last_profile);
            self.send(t, *pan, *tilt);
        }
    }

    pub fn subscribe(&self) -> tokio::sync::broadcast::Receiver<JointSample> {
        self.0.subscribe()
    }
}

/// Unix time (s) of host time `t`: now on the wall clock less (or plus) how long ago it was.
pub fn unix_s_of(t: Instant) -> f64 {
    let now = Instant::now();
    let wall = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs_f64();
    if t <= now {
        wall - now.duration_since(t).as_secs_f64()
    } else {
        wall + t.duration_since(now).as_secs_f64()
    }
}

/// The rig's fixed transforms: the PTU frame (pan and tilt axes' intersection) in the base
/// frame, and the sensor frame in the tilt link's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mount {
    pub ptu_in_base: nalgebra::Isometry3<f64>,
    pub sensor_in_tilt: nalgebra::Isometry3<f64>,
}

impl Mount {
    pub fn of(c: &crate::calibration::Calibration) -> Mount {
        Mount {
            ptu_in_base: c.ptu_in_base,
            sensor_in_tilt: c.sensor_in_tilt,
        }
    }
}

/// A sweep as a backend delivers it: the sweep, and when it happened on this host.
pub struct Swept {
    pub sweep: Sweep,
    pub started: Instant,
    /// When the last profile was exposed (hardware) or the sweep rendered (simulator): where
    /// sweep-to-answer latency starts.
    pub last_profile: Instant,
    /// Where a replayed sweep came from; `None` for a sweep made now.
    pub recorded: Option<Recorded>,
}

/// The recording a replayed sweep was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    /// The sweep id it had when recorded (`None`: a cloud that is not one of the daemon's
    /// recordings). The detector's seed comes from it, so a replay answers as the recording
    /// daemon did.
    pub id: Option<u64>,
    pub file: std::path::PathBuf,
}

/// Why a sweep failed.
#[derive(Debug)]
pub struct SweepFailure {
    pub message: String,
}

/// Health of one device (or of the simulator).
#[derive(Debug, Clone)]
pub struct DeviceStatus {
    pub name: &'static str,
    /// Device path, address or scene file.
    pub path: String,
    pub kind: String,
    pub connected: bool,
    pub last_error: Option<String>,
    pub last_error_at: Option<SystemTime>,
    /// Times the device was (re)opened.
    pub opens: u64,
    pub failures: u64,
    /// The source has nothing more to give, and why (a replay that served every sweep): not a
    /// fault, and nothing will reopen it.
    pub finished: Option<String>,
}

impl DeviceStatus {
    pub fn new(name: &'static str, path: String, kind: String) -> Self {
        DeviceStatus {
            name,
            path,
            kind,
            connected: false,
            last_error: None,
            last_error_at: None,
            opens: 0,
            failures: 0,
            finished: None,
        }
    }

    /// As `status` shows it (docs/PROTOCOL.md).
    pub fn json(&self) -> DeviceJson {
        DeviceJson {
            name: self.name.to_string(),
            path: self.path.clone(),
            kind: self.kind.clone(),
            state: if self.finished.is_some() {
                DeviceState::Finished
            } else if self.connected {
                DeviceState::Ok
            } else if self.last_error.is_some() {
                DeviceState::Fault
            } else {
                DeviceState::Closed
            },
            last_error: self.last_error.clone(),
            last_error_time: self
                .last_error_at
                .and_then(|t| t.duration_since(SystemTime::UNIX_EPOCH).ok())
                .map(|d| d.as_secs_f64()),
            opens: self.opens,
            failures: self.failures,
        }
    }
}

/// The devices' health, written by the backend and read by `status`, error replies and systemd.
#[derive(Debug, Default)]
pub struct Devices(Mutex<Vec<DeviceStatus>>);

impl Devices {
    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<DeviceStatus>> {
        // Status texts and counters, consistent between statements: a panic elsewhere leaves
        // nothing half-written.
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn set(&self, devices: Vec<DeviceStatus>) {
        *self.lock() = devices;
    }

    pub fn snapshot(&self) -> Vec<DeviceStatus> {
        self.lock().clone()
    }

    /// Changes the device called `name` (nothing if there is none).
    pub fn update(&self, name: &str, f: impl FnOnce(&mut DeviceStatus)) {
        if let Some(d) = self.lock().iter_mut().find(|d| d.name == name) {
            f(d);
        }
    }

    /// The device is up: it was (re)opened.
    pub fn note_open(&self, name: &str) {
        self.update(name, |d| {
            d.connected = true;
            d.opens += 1;
        });
    }

    /// The device is down.
    pub fn note_failure(&self, name: &str, message: &str) {
        tracing::warn!("{name}: {message}");
        self.update(name, |d| {
            d.connected = false;
            d.failures += 1;
            d.last_error = Some(message.to_string());
            d.last_error_at = Some(SystemTime::now());
        });
    }

    /// The device is up but a sweep failed on it.
    pub fn note_error(&self, name: &str, message: &str) {
        tracing::warn!("{name}: {message}");
        self.update(name, |d| {
            d.failures += 1;
            d.last_error = Some(message.to_string());
            d.last_error_at = Some(SystemTime::now());
        });
    }

    /// The source has nothing more to give: a replay that served every sweep.
    pub fn note_finished(&self, name: &str, message: &str) {
        tracing::info!("{name}: {message}");
        self.update(name, |d| {
            d.connected = false;
            d.finished = Some(message.to_string());
        });
    }

    /// What finished, when a source did: no sweep will come again.
    pub fn finished(&self) -> Option<String> {
        self.lock()
            .iter()
            .find_map(|d| d.finished.as_ref().map(|why| format!("{} {}: {why}", d.name, d.path)))
    }

    /// One line on what is wrong, for error replies ("" when all is well).
    pub fn trouble(&self) -> String {
        self.lock()
            .iter()
            .filter(|d| !d.connected && d.finished.is_none())
            .map(|d| match &d.last_error {
                Some(e) => format!("{} {} is down: {e}", d.name, d.path),
                None => format!("{} {} is not open yet", d.name, d.path),
            })
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// `ptu ok, sensor down`, for systemd's STATUS.
    pub fn summary(&self) -> String {
        self.lock()
            .iter()
            .map(|d| {
                let state = match (&d.finished, d.connected) {
                    (Some(_), _) => "finished",
                    (None, true) => "ok",
                    (None, false) => "down",
                };
                format!("{} {state}", d.name)
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}
