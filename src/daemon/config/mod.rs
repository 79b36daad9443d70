//! The daemon's configuration file (`/etc/sqscan/sqscand.toml` by default), documented field by
//! field in `docs/DAEMON.md`; `systemd/sqscand.toml` is a complete example.
//!
//! Over 600 lines: the `Config` every task reads and the validation of its sections, one helper
//! a section, beside the defaults they fall back on; the sensor's and the ROS 2 node's tables
//! are in modules of their own.
//!
//! One job, validation, whatever the table: each error must name its field, so every setting
//! is checked here as it is read (the sensor's table, the longest, in `sensor`; the ROS 2 node's in
//! `ros2`).
//!
//! Relative paths in the file are taken relative to the directory the file is in, so a
//! configuration and the calibration it names can move together. With no file at all the daemon
//! runs [`Config::embedded_default`]: the simulated scanner on `scenes/fig3_table.toml`.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;
use sqscan_drivers::PtuKind;
use sqscan_drivers::sensor::SensorConfig;

use crate::spec::{SpecError, read_toml};

mod checks;
pub mod limits;
mod ros2;
mod sensor;
use checks::{count_within, one_of, within};
pub use ros2::Ros2Config;
use ros2::{Ros2File, ros2_config};
use sensor::SensorFile;
pub use sensor::{GigeEndpoint, MAX_ROWS_PER_FRAME, SensorEndpoint};

/// Where the daemon looks for its configuration when `--config` is not given.
pub const DEFAULT_CONFIG_PATH: &str = "/etc/sqscan/sqscand.toml";
/// The socket file name under a runtime directory.
pub const SOCKET_NAME: &str = "sqscand.sock";
/// Requests longer than this are refused (and the rest of the line skipped).
pub const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// The file as written.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    #[serde(default)]
    server: ServerFile,
    #[serde(default)]
    acquisition: AcquisitionFile,
    sim: Option<SimFile>,
    hardware: Option<HardwareFile>,
    replay: Option<ReplayFile>,
    #[serde(default)]
    sweep: SweepFile,
    #[serde(default)]
    detect: DetectFile,
    record: Option<RecordFile>,
    foxglove: Option<FoxgloveFile>,
    ros2: Option<Ros2File>,
    #[serde(default)]
    watch: WatchFile,
    #[serde(default)]
    gripper: crate::grasp::Gripper,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ServerFile {
    socket: Option<PathBuf>,
    /// Permission bits of the socket file, e.g. `0o660`.
    socket_mode: Option<u32>,
    /// `"127.0.0.1:2948"`: also listen on TCP. Off unless given.
    tcp: Option<String>,
    /// Let `tcp` be an address other machines reach (anyone who reaches it drives the sweeps).
    allow_remote: Option<bool>,
    models_dir: Option<PathBuf>,
    max_clients: Option<usize>,
    /// Messages queued for one client before its watch updates are skipped.
    client_queue: Option<usize>,
    /// A client with nothing in flight and no watch is closed after this long (s).
    idle_timeout_s: Option<f64>,
    /// The frame the sweeps' points and the poses are in (the calibration's base frame).
    frame_id: Option<String>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct AcquisitionFile {
    /// `"sim"` or `"hardware"`; default: `"hardware"` when a `[hardware]` table is given.
    backend: Option<String>,
    /// `"continuous"` (default) or `"on_demand"`.
    mode: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimFile {
    scene: PathBuf,
    seed: Option<u64>,
    /// Pace sweeps like the real rig (default true); false renders back to back.
    realtime: Option<bool>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReplayFile {
    /// Recordings (`sweep-*.json` and `.pcd`) or organized PCD files.
    dir: PathBuf,
    /// 1 replays at the recorded pace, 2 twice as fast, 0 as fast as asked (default 1).
    speed: Option<f64>,
    /// Start again after the last (default false: serve each once).
    #[serde(rename = "loop")]
    looping: Option<bool>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct HardwareFile {
    calibration: PathBuf,
    ptu: PtuFile,
    sensor: SensorFile,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PtuFile {
    path: PathBuf,
    protocol: String,
    baud: Option<u32>,
    /// PowerCube module ids.
    pan_module: Option<u8>,
    tilt_module: Option<u8>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    pan_rad: Option<f64>,
    tilt_from_rad: Option<f64>,
    tilt_to_rad: Option<f64>,
    speed_rad_s: Option<f64>,
    /// Sweep back and forth (every other sweep runs from `tilt_to` to `tilt_from`).
    back_and_forth: Option<bool>,
    /// A sweep with fewer kept profiles is dropped.
    min_profiles: Option<usize>,
    /// Pause between sweeps in continuous mode (s).
    pause_s: Option<f64>,
    /// Slack beyond a move's nominal duration before the PTU counts as stuck, and the longest
    /// the sensor may stay silent while acquiring (s).
    timeout_s: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct DetectFile {
    seed: Option<u64>,
    /// Detections run at once at most (each is itself parallel).
    workers: Option<usize>,
    max_range_m: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RecordFile {
    dir: PathBuf,
    /// Keep the newest N recordings (0: keep all).
    keep: Option<usize>,
    /// Also record each sweep as MCAP (the `mcap` feature).
    #[serde(default)]
    mcap: bool,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct FoxgloveFile {
    /// Where the Foxglove WebSocket server listens: a loopback address and port.
    listen: String,
    /// The most a viewer's queue of unsent messages may hold (MB).
    backlog_mb: Option<usize>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct WatchFile {
    /// Objects detected on every sweep whether or not a client asks.
    #[serde(default)]
    objects: Vec<String>,
}

/// Which scanner the daemon drives.
#[derive(Debug, Clone, PartialEq)]
pub enum BackendConfig {
    /// The ray-cast simulator on a scene file.
    Sim { scene: PathBuf, seed: u64, realtime: bool },
    /// A PTU and a profile sensor.
    Hardware(HardwareConfig),
    /// Recorded sweeps served again (see `daemon::replay`).
    Replay { dir: PathBuf, speed: f64, looping: bool },
}

#[derive(Debug, Clone, PartialEq)]
pub struct HardwareConfig {
    pub calibration: PathBuf,
    pub ptu_path: PathBuf,
    pub ptu_kind: PtuKind,
    pub ptu_baud: u32,
    /// PowerCube module ids; `None`: the driver's (pan 12, tilt 11).
    pub pan_module: Option<u8>,
    pub tilt_module: Option<u8>,
    pub sensor: SensorEndpoint,
    pub sensor_baud: u32,
}

/// The sweep the daemon drives; unset angles come from the scene's rig (simulator).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    pub pan_rad: Option<f64>,
    pub tilt_from_rad: Option<f64>,
    pub tilt_to_rad: Option<f64>,
    pub speed_rad_s: Option<f64>,
    pub back_and_forth: bool,
    pub min_profiles: usize,
    pub pause: Duration,
    pub timeout: Duration,
}

/// The validated configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// The file it came from, if any.
    pub source: Option<PathBuf>,
    pub socket: PathBuf,
    pub socket_mode: u32,
    pub tcp: Option<SocketAddr>,
    pub models_dir: PathBuf,
    pub max_clients: usize,
    pub client_queue: usize,
    /// A client with nothing in flight and no watch is closed after this long.
    pub idle_timeout: Duration,
    pub backend: BackendConfig,
    /// Sweep continuously (true) or only when a client needs one.
    pub continuous: bool,
    pub sweep: SweepConfig,
    pub detect_seed: u64,
    pub detect_workers: usize,
    pub max_range_m: Option<f64>,
    pub record_dir: Option<PathBuf>,
    pub record_keep: usize,
    /// Record each sweep as MCAP too, with the watched objects' detections.
    pub record_mcap: bool,
    /// Where the live view (Foxglove WebSocket) listens; `None`: no view.
    pub foxglove_listen: Option<std::net::SocketAddr>,
    /// The bytes a Foxglove viewer's queue of unsent messages holds at most (plus one message).
    pub foxglove_backlog_bytes: usize,
    /// The ROS 2 node; `None`: none.
    pub ros2: Option<Ros2Config>,
    pub watch: Vec<String>,
    /// The frame the sweeps' points and the poses are in, as replies and recordings name it.
    pub frame_id: String,
    /// The gripper grasps are planned for (`find` and `watch` with `"grasps"`).
    pub gripper: crate::grasp::Gripper,
}

/// The socket path when neither the file nor `--socket` names one: under `$XDG_RUNTIME_DIR`
/// when it is set, else in the working directory.
pub fn default_socket_path() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR") {
        Some(d) if !d.is_empty() => PathBuf::from(d).join(SOCKET_NAME),
        _ => PathBuf::from(SOCKET_NAME),
    }
}

/// Where a client looks for the daemon, in order: `$SQSCAN_SOCKET`, the default path, the
/// system service's `/run/sqscan/sqscand.sock`. The first that exists wins; the default path
/// when none does (so the error names it).
pub fn client_socket_candidates() -> Vec<PathBuf> {
    let mut v = Vec::new();
    if let Some(s) = std::env::var_os("SQSCAN_SOCKET") {
        v.push(PathBuf::from(s));
    }
    v.push(default_socket_path());
    v.push(PathBuf::from("/run/sqscan").join(SOCKET_NAME));
    v
}

/// The scenes directory: `./scenes` when it exists (a source checkout), else the package's
/// `/usr/share/sqscan/scenes`.
pub fn default_scenes_dir() -> PathBuf {
    let local = PathBuf::from("scenes");
    if local.is_dir() {
        return local;
    }
    PathBuf::from("/usr/share/sqscan/scenes")
}

impl Config {
    /// The configuration of a machine with no file: the simulator on the Fig. 3 scene.
    pub fn embedded_default() -> Config {
        Config {
            source: None,
            socket: default_socket_path(),
            socket_mode: 0o660,
            tcp: None,
            models_dir: crate::model::default_models_dir(),
            max_clients: 1024,
            client_queue: 64,
            idle_timeout: Duration::from_secs(300),
            backend: BackendConfig::Sim {
                scene: default_scenes_dir().join("fig3_table.toml"),
                seed: 1,
                realtime: true,
            },
            continuous: true,
            sweep: SweepConfig {
                pan_rad: None,
                tilt_from_rad: None,
                tilt_to_rad: None,
                speed_rad_s: None,
                back_and_forth: true,
                min_profiles: 50,
                pause: Duration::ZERO,
                timeout: Duration::from_secs(10),
            },
            detect_seed: 1,
            detect_workers: 2,
            max_range_m: None,
            record_dir: None,
            record_keep: 20,
            record_mcap: false,
            foxglove_listen: None,
            foxglove_backlog_bytes: 32 << 20,
            ros2: None,
            watch: Vec::new(),
            frame_id: "base_link".into(),
            gripper: crate::grasp::Gripper::default(),
        }
    }

    /// Reads and validates a file; errors name the file and the field.
    pub fn from_file(path: &Path) -> Result<Config, SpecError> {
        let raw: ConfigFile = read_toml(path)?;
        Self::validate(raw, path)
    }

    /// Parses text as if it came from `path` (tests, messages).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Config, SpecError> {
        let raw: ConfigFile = crate::spec::parse_toml(text, path)?;
        Self::validate(raw, path)
    }

    fn validate(raw: ConfigFile, path: &Path) -> Result<Config, SpecError> {
        let base = path.parent().unwrap_or(Path::new("."));
        let rel = |p: &Path| -> PathBuf { if p.is_absolute() { p.to_owned() } else { base.join(p) } };
        let mut c = Config::embedded_default();
        c.source = Some(path.to_owned());

        c.apply_server(&raw.server, path, &rel)?;
        c.backend = Self::backend(&raw, path, &rel)?;
        c.continuous = one_of(
            path,
            "acquisition.mode",
            raw.acquisition.mode.as_deref(),
            &[("continuous", true), ("on_demand", false)],
        )?;

        c.apply_sweep(&raw.sweep, path)?;
        c.apply_detect(&raw.detect, path)?;
        if let Some(r) = &raw.record {
            c.apply_record(r, path, &rel)?;
        }
        if let Some(f) = &raw.foxglove {
            c.apply_foxglove(f, path)?;
        }
        if let Some(r) = &raw.ros2 {
            c.ros2 = Some(ros2_config(path, r)?);
        }
        c.watch = raw.watch.objects.clone();
        raw.gripper.validate().map_err(|e| {
            let crate::grasp::GripperError::Field { field, .. } = &e;
            SpecError::invalid(path, format!("gripper.{field}"), e.to_string())
        })?;
        c.gripper = raw.gripper.clone();
        Ok(c)
    }

    /// `[server]`: the socket, TCP, the models, the frame and the client limits.
    fn apply_server(&mut self, s: &ServerFile, path: &Path, rel: &impl Fn(&Path) -> PathBuf) -> Result<(), SpecError> {
        let c = self;
        if let Some(p) = &s.socket {
            c.socket = rel(p);
        }
        if let Some(m) = s.socket_mode {
            if m > 0o777 {
                return Err(SpecError::invalid(
                    path,
                    "server.socket_mode",
                    format!("{m:#o}: give permission bits like 0o660"),
                ));
            }
            c.socket_mode = m;
        }
        if let Some(t) = &s.tcp {
            let addr: SocketAddr = t.parse().map_err(|e| {
                SpecError::invalid(
                    path,
                    "server.tcp",
                    format!("{t:?}: {e}; give an address like \"127.0.0.1:2948\""),
                )
            })?;
            if !addr.ip().is_loopback() && s.allow_remote != Some(true) {
                return Err(SpecError::invalid(
                    path,
                    "server.tcp",
                    format!(
                        "{t:?} is reachable from other machines, and anyone who reaches it drives the sweeps; \
                         give a loopback address, or set server.allow_remote = true"
                    ),
                ));
            }
            c.tcp = Some(addr);
        }
        if let Some(d) = &s.models_dir {
            c.models_dir = rel(d);
        }
        if let Some(f) = &s.frame_id {
            // A ROS name: letters, digits, underscores and slashes, not starting with a digit.
            let ok = f
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_' || c == '/')
                && f.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/');
            if !ok {
                return Err(SpecError::invalid(
                    path,
                    "server.frame_id",
                    format!("{f:?}: give a frame name like \"base_link\" (letters, digits, _ and /)"),
                ));
            }
            c.frame_id = f.clone();
        }
        if let Some(n) = count_within(path, "server.max_clients", s.max_clients, limits::MAX_CLIENTS)? {
            c.max_clients = n;
        }
        if let Some(n) = count_within(path, "server.client_queue", s.client_queue, limits::CLIENT_QUEUE)? {
            c.client_queue = n;
        }
        if let Some(t) = within(
            path,
            "server.idle_timeout_s",
            s.idle_timeout_s,
            limits::IDLE_TIMEOUT_S,
            "s",
        )? {
            c.idle_timeout = Duration::from_secs_f64(t);
        }

        Ok(())
    }

    /// `[acquisition] backend` and the table of the backend it names.
    fn backend(raw: &ConfigFile, path: &Path, rel: &impl Fn(&Path) -> PathBuf) -> Result<BackendConfig, SpecError> {
        let backend = match raw.acquisition.backend.as_deref() {
            None if raw.hardware.is_some() && raw.replay.is_some() => {
                return Err(SpecError::invalid(
                    path,
                    "acquisition.backend",
                    "both [hardware] and [replay] are given: say which to run, \"hardware\" or \"replay\"",
                ));
            }
            None if raw.hardware.is_some() => "hardware",
            None if raw.replay.is_some() => "replay",
            None => "sim",
            Some(b) => b,
        };
        Ok(match backend {
            "sim" => {
                let sim = raw.sim.as_ref();
                BackendConfig::Sim {
                    scene: sim
                        .map(|s| rel(&s.scene))
                        .unwrap_or_else(|| default_scenes_dir().join("fig3_table.toml")),
                    seed: sim.and_then(|s| s.seed).unwrap_or(1),
                    realtime: sim.and_then(|s| s.realtime).unwrap_or(true),
                }
            }
            "hardware" => {
                let h = raw.hardware.as_ref().ok_or_else(|| {
                    SpecError::invalid(path, "hardware", "backend \"hardware\" needs a [hardware] table")
                })?;
                let kind: PtuKind = h
                    .ptu
                    .protocol
                    .parse()
                    .map_err(|e| SpecError::invalid(path, "hardware.ptu.protocol", format!("{e}")))?;
                for (field, id) in [
                    ("hardware.ptu.pan_module", h.ptu.pan_module),
                    ("hardware.ptu.tilt_module", h.ptu.tilt_module),
                ] {
                    if id.is_some_and(|n| !(1..=31).contains(&n)) {
                        return Err(SpecError::invalid(path, field, "give a module id from 1 to 31"));
                    }
                }
                let sensor = sensor::endpoint(path, &h.sensor, rel)?;
                for (field, b) in [
                    ("hardware.ptu.baud", h.ptu.baud),
                    ("hardware.sensor.baud", h.sensor.baud),
                ] {
                    if b == Some(0) {
                        return Err(SpecError::invalid(path, field, "give a baud rate > 0"));
                    }
                }
                BackendConfig::Hardware(HardwareConfig {
                    calibration: rel(&h.calibration),
                    ptu_path: rel(&h.ptu.path),
                    ptu_kind: kind,
                    ptu_baud: h.ptu.baud.unwrap_or(kind.default_baud()),
                    pan_module: h.ptu.pan_module,
                    tilt_module: h.ptu.tilt_module,
                    sensor,
                    sensor_baud: h.sensor.baud.unwrap_or(SensorConfig::default().baud),
                })
            }
            "replay" => {
                let r = raw
                    .replay
                    .as_ref()
                    .ok_or_else(|| SpecError::invalid(path, "replay", "backend \"replay\" needs a [replay] table"))?;
                BackendConfig::Replay {
                    dir: rel(&r.dir),
                    speed: within(
                        path,
                        "replay.speed",
                        r.speed,
                        limits::REPLAY_SPEED,
                        "(times the recorded pace)",
                    )?
                    .unwrap_or(1.0),
                    looping: r.looping.unwrap_or(false),
                }
            }
            other => {
                return Err(SpecError::invalid(
                    path,
                    "acquisition.backend",
                    format!("{other:?}: give \"sim\", \"hardware\" or \"replay\""),
                ));
            }
        })
    }

    /// `[sweep]`: the tilt range and speed (which the hardware backend needs), the profiles a
    /// sweep must keep, its pause and timeout.
    fn apply_sweep(&mut self, w: &SweepFile, path: &Path) -> Result<(), SpecError> {
        let c = self;
        c.sweep.pan_rad = within(path, "sweep.pan_rad", w.pan_rad, limits::ANGLE_RAD, "rad")?;
        c.sweep.tilt_from_rad = within(path, "sweep.tilt_from_rad", w.tilt_from_rad, limits::ANGLE_RAD, "rad")?;
        c.sweep.tilt_to_rad = within(path, "sweep.tilt_to_rad", w.tilt_to_rad, limits::ANGLE_RAD, "rad")?;
        c.sweep.speed_rad_s = within(path, "sweep.speed_rad_s", w.speed_rad_s, limits::SPEED_RAD_S, "rad/s")?;
        if let (Some(a), Some(b)) = (c.sweep.tilt_from_rad, c.sweep.tilt_to_rad)
            && a == b
        {
            return Err(SpecError::invalid(
                path,
                "sweep.tilt_to_rad",
                "equals tilt_from_rad: a sweep needs a range",
            ));
        }
        if matches!(c.backend, BackendConfig::Hardware(_))
            && (c.sweep.tilt_from_rad.is_none() || c.sweep.tilt_to_rad.is_none() || c.sweep.speed_rad_s.is_none())
        {
            return Err(SpecError::invalid(
                path,
                "sweep",
                "the hardware backend needs tilt_from_rad, tilt_to_rad and speed_rad_s",
            ));
        }
        if let Some(b) = w.back_and_forth {
            c.sweep.back_and_forth = b;
        }
        if let Some(n) = count_within(path, "sweep.min_profiles", w.min_profiles, limits::MIN_PROFILES)? {
            c.sweep.min_profiles = n;
        }
        if let Some(p) = within(path, "sweep.pause_s", w.pause_s, limits::PAUSE_S, "s")? {
            c.sweep.pause = Duration::from_secs_f64(p);
        }
        if let Some(t) = within(path, "sweep.timeout_s", w.timeout_s, limits::TIMEOUT_S, "s")? {
            c.sweep.timeout = Duration::from_secs_f64(t);
        }
        // A sweep slower than this is a unit slip, and would hold every answer for hours.
        if let (Some(a), Some(b), Some(v)) = (c.sweep.tilt_from_rad, c.sweep.tilt_to_rad, c.sweep.speed_rad_s) {
            let takes = (b - a).abs() / v;
            if takes > limits::SWEEP_S {
                return Err(SpecError::invalid(
                    path,
                    "sweep.speed_rad_s",
                    format!(
                        "a sweep from {a} to {b} rad at {v} rad/s takes {takes:.0} s; give a speed that sweeps in at most {} s",
                        limits::SWEEP_S
                    ),
                ));
            }
        }

        Ok(())
    }

    /// `[detect]`: the seed, the workers and the range cut.
    fn apply_detect(&mut self, d: &DetectFile, path: &Path) -> Result<(), SpecError> {
        let c = self;
        if let Some(s) = d.seed {
            c.detect_seed = s;
        }
        if let Some(n) = count_within(path, "detect.workers", d.workers, limits::WORKERS)? {
            c.detect_workers = n;
        }
        c.max_range_m = within(path, "detect.max_range_m", d.max_range_m, limits::MAX_RANGE_M, "m")?;

        Ok(())
    }

    /// `[record]`: where sweeps are recorded, how many are kept, and whether as MCAP.
    fn apply_record(&mut self, r: &RecordFile, path: &Path, rel: &impl Fn(&Path) -> PathBuf) -> Result<(), SpecError> {
        let c = self;
        c.record_dir = Some(rel(&r.dir));
        c.record_keep = count_within(path, "record.keep", r.keep, limits::RECORD_KEEP)?.unwrap_or(20);
        if r.mcap && !cfg!(feature = "mcap") {
            return Err(SpecError::invalid(
                path,
                "record.mcap",
                "this sqscand was built without MCAP recording (cargo feature `mcap`)",
            ));
        }
        c.record_mcap = r.mcap;
        Ok(())
    }

    /// `[foxglove]`: the live view's address (loopback only) and its backlog.
    fn apply_foxglove(&mut self, f: &FoxgloveFile, path: &Path) -> Result<(), SpecError> {
        let c = self;
        let addr: std::net::SocketAddr = f.listen.parse().map_err(|_| {
            SpecError::invalid(
                path,
                "foxglove.listen",
                format!("{:?}: give an address and port, e.g. \"127.0.0.1:8765\"", f.listen),
            )
        })?;
        if !addr.ip().is_loopback() {
            return Err(SpecError::invalid(
                path,
                "foxglove.listen",
                format!(
                    "{addr}: the view has no authentication, so it listens on loopback only \
                     (reach it from elsewhere through an SSH tunnel)"
                ),
            ));
        }
        if !cfg!(feature = "foxglove") {
            return Err(SpecError::invalid(
                path,
                "foxglove.listen",
                "this sqscand was built without the live view (cargo feature `foxglove`)",
            ));
        }
        c.foxglove_listen = Some(addr);
        if let Some(mb) = count_within(path, "foxglove.backlog_mb", f.backlog_mb, limits::VIEW_BACKLOG_MB)? {
            c.foxglove_backlog_bytes = mb << 20;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
