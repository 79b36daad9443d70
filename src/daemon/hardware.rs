//! The hardware backend: a pan-tilt unit and a profile sensor, opened (and reopened after a
//! fault, with backoff) by the daemon, swept with [`crate::sweep::acquire()`].

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use sqscan_drivers::sensor::{ProfileSensor, ProfileSource, ReceivedProfile, SensorConfig};
use sqscan_drivers::{AnyPtu, Error as DriverError, Link, PanTilt, PtuSettings, SerialLink};

use crate::calibration::Calibration;
use crate::sweep::{self, SweepError, SweepSettings};

use super::backend::{Backend, DeviceStatus, Devices, JointFeed, SweepFailure, Swept};
use super::config::{HardwareConfig, SensorEndpoint, SweepConfig};

/// First and longest wait before reopening a device that failed.
const BACKOFF_MIN: Duration = Duration::from_millis(250);
const BACKOFF_MAX: Duration = Duration::from_secs(5);

/// Any sensor link; `Sync` because the sweep future holds references to it across awaits and
/// must be `Send`.
pub trait SensorLink: Link + Sync {}
impl<T: Link + Sync> SensorLink for T {}

/// The configured profile sensor: an SQPF stream, or a GigE Vision camera.
enum Sensor {
    Sqpf(ProfileSensor<Box<dyn SensorLink>>),
    #[cfg(feature = "gige")]
    Gige(sqscan_drivers::gige::camera::GigeSensor),
}

impl ProfileSource for Sensor {
    async fn start(&mut self) -> Result<(), DriverError> {
        match self {
            Sensor::Sqpf(s) => s.start().await,
            #[cfg(feature = "gige")]
            Sensor::Gige(s) => ProfileSource::start(s).await,
        }
    }

    async fn stop(&mut self) -> Result<(), DriverError> {
        match self {
            Sensor::Sqpf(s) => s.stop().await,
            #[cfg(feature = "gige")]
            Sensor::Gige(s) => ProfileSource::stop(s).await,
        }
    }

    async fn next_profile(&mut self, wait: Duration) -> Result<ReceivedProfile, DriverError> {
        match self {
            Sensor::Sqpf(s) => s.next_profile(wait).await,
            #[cfg(feature = "gige")]
            Sensor::Gige(s) => ProfileSource::next_profile(s, wait).await,
        }
    }
}

/// Closes a sensor and waits until it is released, so that the next open (the acquisition's, or
/// another program's) finds it free.
async fn close_sensor(sensor: Sensor) {
    match sensor {
        Sensor::Sqpf(s) => drop(s),
        #[cfg(feature = "gige")]
        Sensor::Gige(c) => {
            let _ = tokio::task::spawn_blocking(move || c.close()).await;
        }
    }
}

/// A device slot: the open device or when to try opening it again.
struct Slot<T> {
    device: Option<T>,
    backoff: Duration,
    next_try: Instant,
}

impl<T> Slot<T> {
    fn new() -> Self {
        Slot {
            device: None,
            backoff: BACKOFF_MIN,
            next_try: Instant::now(),
        }
    }

    fn failed(&mut self) {
        self.device = None;
        self.next_try = Instant::now() + self.backoff;
        self.backoff = (self.backoff * 2).min(BACKOFF_MAX);
    }

    fn opened(&mut self, d: T) {
        self.device = Some(d);
        self.backoff = BACKOFF_MIN;
    }
}

pub struct HardwareBackend {
    cfg: HardwareConfig,
    calib: Calibration,
    settings: SweepSettings,
    ptu: Slot<AnyPtu<SerialLink>>,
    sensor: Slot<Sensor>,
}

impl HardwareBackend {
    /// The configured serial devices as start-up finds them: an error for a path that exists
    /// and is not a terminal device (a regular file, a directory, `/dev/null`), and a warning for
    /// one that does not exist yet (a USB adapter plugged in later) or cannot be opened by this
    /// user; the warnings are returned.
    pub fn check_devices(cfg: &HardwareConfig) -> Result<Vec<String>> {
        let mut warnings = Vec::new();
        let mut devices = vec![("hardware.ptu.path", cfg.ptu_path.as_path())];
        if let SensorEndpoint::Serial(p) = &cfg.sensor {
            devices.push(("hardware.sensor.path", p.as_path()));
        }
        for (field, path) in devices {
            if let Some(w) = check_device(field, path)? {
                warnings.push(w);
            }
        }
        Ok(warnings)
    }

    pub fn new(cfg: &HardwareConfig, sweep_cfg: &SweepConfig) -> Result<HardwareBackend> {
        let calib = Calibration::from_file(&cfg.calibration)
            .map_err(|e| anyhow::anyhow!(e.with_causes()))
            .context("loading the calibration")?;
        let d = SweepSettings::default();
        let settings = SweepSettings {
            pan_rad: sweep_cfg.pan_rad.unwrap_or(d.pan_rad),
            tilt_from_rad: sweep_cfg.tilt_from_rad.unwrap_or(d.tilt_from_rad),
            tilt_to_rad: sweep_cfg.tilt_to_rad.unwrap_or(d.tilt_to_rad),
            speed_rad_s: sweep_cfg.speed_rad_s.unwrap_or(d.speed_rad_s),
            min_profiles: sweep_cfg.min_profiles,
            timeout: sweep_cfg.timeout,
            ..d
        };
        settings.validate().context("sweep settings")?;
        Ok(HardwareBackend {
            cfg: cfg.clone(),
            calib,
            settings,
            ptu: Slot::new(),
            sensor: Slot::new(),
        })
    }

    /// How the configured PTU is opened: its line speed, module ids and the calibration's axes.
    fn ptu_settings(&self) -> PtuSettings {
        PtuSettings {
            baud: Some(self.cfg.ptu_baud),
            pan: self.calib.pan_axis(),
            tilt: self.calib.tilt_axis(),
            pan_module: self.cfg.pan_module,
            tilt_module: self.cfg.tilt_module,
        }
    }

    async fn open_ptu(&self) -> Result<AnyPtu<SerialLink>, DriverError> {
        let path = &self.cfg.ptu_path;
        let mut ptu = self.cfg.ptu_kind.open(path, &self.ptu_settings()).await?;
        // A unit that lost its reference (power cycle) or latched a fault (the unplug) must be
        // homed before it moves; one that is fine is left where it is.
        let state = ptu.state().await?;
        if !(state.pan.homed && state.tilt.homed) || state.pan.fault || state.tilt.fault {
            tracing::info!("homing the PTU on {}", path.display());
            ptu.home().await?;
        }
        Ok(ptu)
    }

    async fn open_sensor(&self) -> Result<Sensor, DriverError> {
        let cfg = SensorConfig {
            baud: self.cfg.sensor_baud,
            ..SensorConfig::default()
        };
        Ok(match &self.cfg.sensor {
            SensorEndpoint::Serial(p) => {
                let link: Box<dyn SensorLink> = Box::new(sqscan_drivers::open_serial(p, cfg.baud)?);
                Sensor::Sqpf(ProfileSensor::new(link, cfg))
            }
            SensorEndpoint::Tcp(a) => {
                let s = ProfileSensor::connect_tcp(a, cfg.clone()).await?;
                let link: Box<dyn SensorLink> = Box::new(s.into_inner());
                Sensor::Sqpf(ProfileSensor::new(link, cfg))
            }
            #[cfg(feature = "gige")]
            SensorEndpoint::Gige(g) => {
                use sqscan_drivers::gige::StampedRow;
                use sqscan_drivers::gige::camera::{GigeConfig, GigeSensor};
                let mut c = GigeConfig::new(g.address.clone());
                c.features = g.features.clone();
                c.rows_per_frame = g.rows_per_frame;
                c.fraction_bits = self.calib.fraction_bits;
                c.stamped = if g.stamp_last_row {
                    StampedRow::Last
                } else {
                    StampedRow::First
                };
                let camera = GigeSensor::open(c).await?;
                let info = camera.info();
                if info.width != self.calib.columns {
                    return Err(DriverError::Feature {
                        feature: "Width".into(),
                        message: format!(
                            "the camera sends {} columns, the calibration has {}",
                            info.width, self.calib.columns
                        ),
                    });
                }
                tracing::info!(
                    "camera {} {} ({}): {} columns, {} profiles a block at {} Hz, {}",
                    info.vendor,
                    info.model,
                    info.serial,
                    info.width,
                    info.rows_per_frame,
                    info.line_rate_hz,
                    info.pixel_format
                );
                Sensor::Gige(camera)
            }
            #[cfg(not(feature = "gige"))]
            SensorEndpoint::Gige(g) => {
                return Err(DriverError::Camera(format!(
                    "{}: this sqscand was built without GigE Vision support (cargo feature gige)",
                    g.address
                )));
            }
        })
    }

    /// At start-up, a GigE Vision camera that answers but lacks a feature the sensor needs, or
    /// refuses a value the configuration sets, stops the start naming the feature: retrying
    /// would not change it. One that does not answer yet is left to the acquisition, which
    /// retries it with backoff (a robot may power its camera later). A camera that opens is kept
    /// open for the first sweep. Other sensors and the PTU are opened by the acquisition alone.
    pub async fn check_camera(&mut self) -> Result<()> {
        if !matches!(self.cfg.sensor, SensorEndpoint::Gige(_)) {
            return Ok(());
        }
        match self.open_sensor().await {
            Ok(sensor) => {
                tracing::info!("sensor open on {}", self.cfg.sensor);
                self.sensor.opened(sensor);
                Ok(())
            }
            Err(e @ DriverError::Feature { .. }) => Err(anyhow::anyhow!(
                "sensor {}: {e} (docs/DAEMON.md lists the features the sensor needs)",
                self.cfg.sensor
            )),
            Err(e) => {
                tracing::warn!("sensor {}: {e}; trying again once the daemon runs", self.cfg.sensor);
                Ok(())
            }
        }
    }

    /// `sqscand --check --probe`: opens each configured device and says what it found, one line
    /// a device, leaving the PTU where it stands (no homing, no move) and the sensor stopped.
    /// An SQPF sensor is started for one profile.
    pub async fn probe(&self) -> Result<Vec<String>> {
        let ptu_line = self
            .probe_ptu()
            .await
            .with_context(|| format!("ptu {}", self.cfg.ptu_path.display()))?;
        let sensor_line = self
            .probe_sensor()
            .await
            .with_context(|| format!("sensor {}", self.cfg.sensor))?;
        Ok(vec![ptu_line, sensor_line])
    }

    async fn probe_ptu(&self) -> Result<String> {
        let mut ptu = self.cfg.ptu_kind.open(&self.cfg.ptu_path, &self.ptu_settings()).await?;
        let state = ptu.state().await?;
        let l = ptu.limits();
        let axis = |a: &sqscan_drivers::AxisState| {
            format!(
                "{:.4} rad{}{}",
                a.position_rad,
                if a.homed { "" } else { ", not homed" },
                if a.fault { ", fault" } else { "" }
            )
        };
        Ok(format!(
            "ptu {}: {} at {} baud: pan {}, tilt {}; limits pan [{:.4}, {:.4}] rad, tilt [{:.4}, {:.4}] rad",
            self.cfg.ptu_path.display(),
            self.cfg.ptu_kind.model(),
            self.cfg.ptu_baud,
            axis(&state.pan),
            axis(&state.tilt),
            l.pan_rad.0,
            l.pan_rad.1,
            l.tilt_rad.0,
            l.tilt_rad.1
        ))
    }

    async fn probe_sensor(&self) -> Result<String> {
        let mut sensor = self.open_sensor().await?;
        let line = match &mut sensor {
            Sensor::Sqpf(s) => {
                s.start().await?;
                let first = s.next_profile(Duration::from_secs(2)).await;
                let stopped = s.stop().await;
                let p = first?.profile;
                stopped?;
                let mut line = format!(
                    "sensor {}: SQPF profiles of {} columns, {} fraction bits{}",
                    self.cfg.sensor,
                    p.columns(),
                    p.fraction_bits,
                    if p.intensity.is_some() { ", with intensity" } else { "" }
                );
                if p.columns() != self.calib.columns || p.fraction_bits != self.calib.fraction_bits {
                    line.push_str(&format!(
                        " (the calibration has {} columns, {} fraction bits: its profiles would be dropped)",
                        self.calib.columns, self.calib.fraction_bits
                    ));
                }
                line
            }
            #[cfg(feature = "gige")]
            Sensor::Gige(c) => {
                let i = c.info();
                format!(
                    "sensor {}: {} {} (serial {}): {} columns, {} profiles a block at {} Hz, {}",
                    self.cfg.sensor,
                    i.vendor,
                    i.model,
                    i.serial,
                    i.width,
                    i.rows_per_frame,
                    i.line_rate_hz,
                    i.pixel_format
                )
            }
        };
        close_sensor(sensor).await;
        Ok(line)
    }

    /// Opens what is closed (respecting each device's backoff), waiting at most until the
    /// sooner retry when a device is still down.
    async fn ensure_open(&mut self, devices: &Devices) -> Result<(), SweepFailure> {
        loop {
            let now = Instant::now();
            if self.ptu.device.is_none() && now >= self.ptu.next_try {
                match self.open_ptu().await {
                    Ok(p) => {
                        self.ptu.opened(p);
                        devices.note_open("ptu");
                        tracing::info!("PTU open on {}", self.cfg.ptu_path.display());
                    }
                    Err(e) => {
                        self.ptu.failed();
                        devices.note_failure("ptu", &e.to_string());
                    }
                }
            }
            if self.sensor.device.is_none() && Instant::now() >= self.sensor.next_try {
                match self.open_sensor().await {
                    Ok(s) => {
                        self.sensor.opened(s);
                        devices.note_open("sensor");
                        tracing::info!("sensor open on {}", self.cfg.sensor);
                    }
                    Err(e) => {
                        self.sensor.failed();
                        devices.note_failure("sensor", &e.to_string());
                    }
                }
            }
            if self.ptu.device.is_some() && self.sensor.device.is_some() {
                return Ok(());
            }
            let wake = [&self.ptu.next_try, &self.sensor.next_try]
                .into_iter()
                .zip([self.ptu.device.is_none(), self.sensor.device.is_none()])
                .filter(|(_, down)| *down)
                .map(|(t, _)| *t)
                .min()
                .unwrap_or_else(Instant::now);
            tokio::time::sleep_until(wake.into()).await;
        }
    }
}

impl Backend for HardwareBackend {
    fn name(&self) -> &'static str {
        "hardware"
    }

    fn devices(&self) -> Vec<DeviceStatus> {
        let mut sensor = DeviceStatus::new(
            "sensor",
            self.cfg.sensor.to_string(),
            match self.cfg.sensor {
                SensorEndpoint::Gige(_) => "GigE Vision line-profile camera",
                _ => "SQPF profile sensor",
            }
            .into(),
        );
        // A camera opened by the start-up check.
        if self.sensor.device.is_some() {
            sensor.connected = true;
            sensor.opens = 1;
        }
        vec![
            DeviceStatus::new(
                "ptu",
                self.cfg.ptu_path.display().to_string(),
                format!("{} at {} baud", self.cfg.ptu_kind.model(), self.cfg.ptu_baud),
            ),
            sensor,
        ]
    }

    async fn sweep(&mut self, forward: bool, devices: &Devices, joints: &JointFeed) -> Result<Swept, SweepFailure> {
        self.ensure_open(devices).await?;
        let settings = if forward {
            self.settings.clone()
        } else {
            self.settings.reversed()
        };
        let (Some(ptu), Some(sensor)) = (self.ptu.device.as_mut(), self.sensor.device.as_mut()) else {
            return Err(SweepFailure {
                message: "devices not open".into(),
            });
        };
        let result = sweep::acquire_live(ptu, sensor, &self.calib, &settings, |s| {
            joints.send(s.t, s.pan_rad, s.tilt_rad)
        })
        .await;
        match result {
            Ok(mut sweep) => {
                sweep.report.profile_times = match self.cfg.sensor {
                    SensorEndpoint::Gige(_) => "block_and_line_rate",
                    _ => "profile",
                }
                .into();
                // Assembled sweeps always carry their start; now is the fallback that cannot lie
                // by much.
                let started = sweep.start.unwrap_or_else(Instant::now);
                let last = sweep.stamp_s.last().copied().unwrap_or(0.0).max(0.0);
                Ok(Swept {
                    started,
                    last_profile: started + Duration::from_secs_f64(last),
                    sweep,
                    recorded: None,
                })
            }
            Err(e) => {
                let message = e.to_string();
                match &e {
                    // The link is gone or the unit faulted: close it; the next sweep reopens it
                    // (and homes it if it lost its reference).
                    SweepError::Ptu(d) if !d.is_transient() => {
                        self.ptu.failed();
                        devices.note_failure("ptu", &d.to_string());
                    }
                    SweepError::Ptu(d) => devices.note_error("ptu", &d.to_string()),
                    SweepError::PtuStopped { .. } => devices.note_error("ptu", &message),
                    SweepError::Sensor(d) => {
                        // A silent or broken sensor is reopened: it may have been restarted.
                        self.sensor.failed();
                        devices.note_failure("sensor", &d.to_string());
                    }
                    _ => {}
                }
                Err(SweepFailure { message })
            }
        }
    }

    /// Stops the unit where it is (best effort, bounded: the daemon is stopping).
    async fn stop(&mut self) {
        let halt = async {
            match self.ptu.device.as_mut() {
                Some(p) => p.halt().await,
                None => Ok(()),
            }
        };
        let _ = tokio::time::timeout(Duration::from_millis(300), halt).await;
        if let Some(s) = self.sensor.device.as_mut() {
            let _ = tokio::time::timeout(Duration::from_millis(200), s.stop()).await;
        }
    }

    fn mount(&self) -> Option<super::backend::Mount> {
        Some(super::backend::Mount::of(&self.calib))
    }
}

/// One device path of [`HardwareBackend::check_devices`].
fn check_device(field: &str, path: &std::path::Path) -> Result<Option<String>> {
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    let shown = crate::spec::escape_controls(&path.display().to_string());
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(Some(format!(
                "{field}: {shown} does not exist (yet); it is opened when it appears"
            )));
        }
        Err(e) => anyhow::bail!("{field}: {shown}: {e}"),
    };
    if !meta.file_type().is_char_device() {
        let what = if meta.is_dir() {
            "a directory"
        } else if meta.is_file() {
            "a regular file"
        } else {
            "not a device"
        };
        anyhow::bail!("{field}: {shown} is {what}, not a serial device");
    }
    // Opened without becoming the controlling terminal and without waiting for carrier; only
    // asked whether it is a terminal (a serial port is; /dev/null, /dev/zero are not).
    let file = match std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
        .open(path)
    {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {
            return Ok(Some(format!("{field}: {shown}: cannot open it as this user ({e})")));
        }
        Err(e) => {
            return Ok(Some(format!(
                "{field}: {shown}: cannot open it now ({e}); it is retried"
            )));
        }
    };
    if !std::io::IsTerminal::is_terminal(&file) {
        anyhow::bail!("{field}: {shown} is a character device but not a terminal: not a serial port");
    }
    Ok(None)
}

#[cfg(test)]
mod device_tests {
    use super::check_device;

    #[test]
    fn a_ptu_path_must_be_a_serial_device() {
        let dir = std::env::temp_dir().join(format!("sqscan-devcheck-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("ttyUSB0");
        std::fs::write(&file, b"").unwrap();
        for (path, says) in [
            (std::path::Path::new("/dev/null"), "not a terminal"),
            (file.as_path(), "a regular file"),
            (dir.as_path(), "a directory"),
        ] {
            let e = check_device("hardware.ptu.path", path).unwrap_err().to_string();
            assert!(e.contains("hardware.ptu.path") && e.contains(says), "{e}");
        }
        // Not there yet: a warning, since it may be plugged in later.
        let w = check_device("hardware.ptu.path", &dir.join("missing"))
            .unwrap()
            .unwrap();
        assert!(w.contains("does not exist"), "{w}");
        // A pseudo-terminal, as the mock devices use, is a terminal.
        // SAFETY: a pty pair from the C library; the master stays open while it is checked.
        let slave = unsafe {
            let master = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY);
            assert!(master >= 0);
            assert_eq!(libc::grantpt(master), 0);
            assert_eq!(libc::unlockpt(master), 0);
            let mut name = [0 as libc::c_char; 128];
            assert_eq!(libc::ptsname_r(master, name.as_mut_ptr(), name.len()), 0);
            (
                master,
                std::ffi::CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned(),
            )
        };
        assert_eq!(
            check_device("hardware.ptu.path", std::path::Path::new(&slave.1)).unwrap(),
            None
        );
        // SAFETY: the master opened above.
        unsafe { libc::close(slave.0) };
        let _ = std::fs::remove_dir_all(&dir);
    }
}
