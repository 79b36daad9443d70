//! `sqscan mock ...`: mock devices on pseudo-terminals, used exactly like hardware.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use sqscan_drivers::PtuKind;
use sqscan_drivers::mock::{Faults, MockPort, ServeEnd};
use std::path::{Path, PathBuf};
use std::time::Duration;

use super::ptu::ptu_kind_parser;

#[derive(Args)]
pub struct MockArgs {
    #[command(subcommand)]
    device: MockDevice,
}

// Parsed once at start: the size of the rig's arguments does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum MockDevice {
    /// Run a mock pan-tilt unit on a pty until interrupted
    Ptu(MockPtuArgs),
    /// Run the mock scanning rig until interrupted: a mock PTU on one pty and a mock profile
    /// sensor on another that sees the scene from the PTU's current angles
    Rig(MockRigArgs),
}

#[derive(Args)]
pub struct MockRigArgs {
    #[command(flatten)]
    pub models: crate::ModelsDirArg,
    /// Scene file whose table, objects and rig the sensor sees
    #[arg(long, value_name = "SCENE")]
    scene: PathBuf,
    /// The protocol the mock PTU speaks
    #[arg(long, value_parser = ptu_kind_parser())]
    protocol: PtuKind,
    /// Keep a symlink to the PTU's pty here
    #[arg(long, value_name = "PATH")]
    ptu_link: Option<PathBuf>,
    /// Keep a symlink to the sensor's pty here
    #[arg(long, value_name = "PATH")]
    sensor_link: Option<PathBuf>,
    /// Profiles a second while acquiring
    #[arg(long, value_name = "HZ", default_value_t = 50.0)]
    rate: f64,
    /// The sensor: an SQPF stream on a pty, or a GigE Vision line-profile camera (aravis's
    /// camera emulator; needs the gige feature) on --gige-address, alongside the idle SQPF pty
    #[arg(long, value_name = "KIND", default_value = "sqpf", value_parser = ["sqpf", "gige"])]
    sensor: String,
    /// Interface address the GigE Vision camera serves on (run it in a private network
    /// namespace: see drivers/README.md)
    #[arg(long, value_name = "ADDRESS", default_value = "127.0.0.1")]
    gige_address: String,
    /// Profiles a GigE Vision block (the camera's Height)
    #[arg(long, value_name = "N", default_value_t = 10)]
    rows_per_frame: u32,
    /// The GigE Vision camera's clock reads this much ahead of the host's (s)
    #[arg(long, value_name = "SECS", default_value_t = 1234.5, allow_negative_numbers = true)]
    camera_clock_offset: f64,
    /// ...and runs this much fast (ppm; negative: slow)
    #[arg(long, value_name = "PPM", default_value_t = 0.0, allow_negative_numbers = true)]
    camera_clock_drift: f64,
    /// Unplug the GigE Vision camera SECS after the rig starts (the emulator stops and closes its
    /// sockets)...
    #[arg(long, value_name = "SECS")]
    camera_unplug_after: Option<f64>,
    /// ...and plug a fresh one in on the same address SECS later
    #[arg(long, value_name = "SECS", requires = "camera_unplug_after")]
    camera_replug_after: Option<f64>,
    /// After the PTU's --disconnect-after unplug, plug the same unit back in SECS later: a new
    /// pty, the --ptu-link symlink re-pointed at it, same angles; once (it is not unplugged
    /// again). The sensor keeps streaming meanwhile
    #[arg(long, value_name = "SECS", requires = "disconnect_after")]
    ptu_replug_after: Option<f64>,
    /// How the unit's tilt is mounted: joint tilt = SIGN x device tilt. -1 for a PTU-D46, which
    /// tilts down at negative positions (use it with calibration/sim_rig_flir.toml)
    #[arg(long, value_name = "SIGN", default_value_t = 1, allow_negative_numbers = true,
          value_parser = clap::value_parser!(i8).range(-1..=1))]
    tilt_sign: i8,
    /// PTU fault injection; --seed also seeds the sensor noise
    #[command(flatten)]
    faults: FaultArgs,
    #[command(flatten)]
    sensor_faults: SensorFaultArgs,
}

/// Sensor fault injection; counters are over frames, 0 disables.
#[derive(Args)]
pub struct SensorFaultArgs {
    /// Send 1-16 random bytes before every Nth frame
    #[arg(long, value_name = "N", default_value_t = 0)]
    sensor_garbage_every: u64,
    /// Drop every Nth frame (its sequence number is used up)
    #[arg(long, value_name = "N", default_value_t = 0)]
    sensor_drop_every: u64,
    /// Send every Nth frame with a bad CRC
    #[arg(long, value_name = "N", default_value_t = 0)]
    sensor_corrupt_every: u64,
    /// Close the sensor's pty (unplug) after N frames
    #[arg(long, value_name = "N")]
    sensor_disconnect_after: Option<u64>,
}

#[derive(Args)]
pub struct MockPtuArgs {
    /// The protocol the mock PTU speaks
    #[arg(long, value_parser = ptu_kind_parser())]
    protocol: PtuKind,
    /// Keep a symlink to the pty here (replaced if it is a symlink)
    #[arg(long, value_name = "PATH")]
    link: Option<PathBuf>,
    #[command(flatten)]
    faults: FaultArgs,
}

/// Fault injection; counters are over replies sent, 0 disables.
#[derive(Args)]
pub struct FaultArgs {
    /// Send 1-16 random bytes before every Nth reply
    #[arg(long, value_name = "N", default_value_t = 0)]
    garbage_every: u64,
    /// Drop every Nth reply
    #[arg(long, value_name = "N", default_value_t = 0)]
    drop_every: u64,
    /// Send every Nth reply with a bad checksum
    #[arg(long, value_name = "N", default_value_t = 0)]
    corrupt_every: u64,
    /// Delay every reply by this many milliseconds
    #[arg(long, value_name = "MS", default_value_t = 0)]
    delay_ms: u64,
    /// Close the pty (unplug) after N replies
    #[arg(long, value_name = "N")]
    disconnect_after: Option<u64>,
    /// After an unplug, plug a fresh device in (new pty, same link) after this many milliseconds
    #[arg(long, value_name = "MS", requires = "disconnect_after")]
    replug_after_ms: Option<u64>,
    /// Seed of the garbage bytes (and, for the rig, of the sensor noise)
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl FaultArgs {
    fn faults(&self) -> Faults {
        Faults {
            garbage_every: self.garbage_every,
            drop_every: self.drop_every,
            corrupt_every: self.corrupt_every,
            delay: Duration::from_millis(self.delay_ms),
            disconnect_after: self.disconnect_after,
            seed: self.seed,
        }
    }
}

pub fn run(a: MockArgs) -> Result<()> {
    // The rig's sensor renders the scene on its task: a second worker keeps the PTU answering
    // meanwhile.
    let workers = if matches!(a.device, MockDevice::Rig(_)) { 2 } else { 1 };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(workers)
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    match a.device {
        MockDevice::Ptu(p) => rt.block_on(mock_ptu(p)),
        MockDevice::Rig(r) => {
            let models_dir = r.models.dir();
            rt.block_on(mock_rig(r, &models_dir))
        }
    }
}

async fn mock_rig(a: MockRigArgs, models_dir: &Path) -> Result<()> {
    use sqscan::mock::rig::RigMock;
    if a.faults.replug_after_ms.is_some() {
        anyhow::bail!(
            "--replug-after-ms is for `sqscan mock ptu`: the rig's PTU comes back with --ptu-replug-after SECS"
        );
    }
    let cfg = rig_config(&a)?;
    let scene = std::sync::Arc::new(sqscan::sim::Scene::from_file(&a.scene, models_dir)?);
    let columns = scene.rig.sensor.columns;
    let rig = RigMock::start(scene.clone(), &cfg, a.ptu_link.as_deref(), a.sensor_link.as_deref())
        .context("cannot start the mock rig")?;
    println!(
        "mock rig: {} PTU on {}",
        a.protocol.model(),
        shown(&rig.ptu_path, &a.ptu_link)
    );
    println!(
        "mock rig: sensor ({columns} columns, {} Hz) on {}",
        a.rate,
        shown(&rig.sensor_path, &a.sensor_link)
    );
    let unplug_after = seconds("--camera-unplug-after", a.camera_unplug_after)?;
    let replug_after = seconds("--camera-replug-after", a.camera_replug_after)?;
    // Kept until the rig stops, or unplugged and plugged back in when asked to.
    let _camera = if a.sensor == "gige" {
        let camera = CameraPlug {
            args: a.clone_camera_args(),
            scene,
            ptu: rig.ptu.clone(),
            cfg: cfg.clone(),
        };
        camera.start(unplug_after, replug_after)?
    } else {
        if unplug_after.is_some() {
            anyhow::bail!("--camera-unplug-after is for --sensor gige");
        }
        drop(scene);
        None
    };
    let RigMock {
        ptu_task,
        sensor_task,
        ptu_replugged,
        ..
    } = rig;
    tokio::spawn(announce_replugged_ptu(ptu_replugged, a.ptu_link.clone()));
    let result = tokio::select! {
        r = ptu_task => r.context("mock PTU task failed")?.map(|end| println!("PTU {end:?}")).context("mock PTU line failed"),
        r = sensor_task => r.context("mock sensor task failed")?.map(|end| println!("sensor {end:?}")).context("mock sensor line failed"),
        r = shutdown_signal() => r,
    };
    for link in [&a.ptu_link, &a.sensor_link].into_iter().flatten() {
        let _ = std::fs::remove_file(link);
    }
    result
}

/// The rig's devices and faults from the command line.
fn rig_config(a: &MockRigArgs) -> Result<sqscan::mock::rig::RigConfig> {
    Ok(sqscan::mock::rig::RigConfig {
        ptu_kind: a.protocol,
        rate_hz: a.rate,
        seed: a.faults.seed,
        ptu_faults: a.faults.faults(),
        sensor_faults: Faults {
            garbage_every: a.sensor_faults.sensor_garbage_every,
            drop_every: a.sensor_faults.sensor_drop_every,
            corrupt_every: a.sensor_faults.sensor_corrupt_every,
            delay: Duration::ZERO,
            disconnect_after: a.sensor_faults.sensor_disconnect_after,
            seed: a.faults.seed,
        },
        ptu_replug_after: seconds("--ptu-replug-after", a.ptu_replug_after)?,
        tilt_axis: sqscan_drivers::AxisConfig::new(f64::from(a.tilt_sign), 0.0)
            .map_err(|e| anyhow::anyhow!("--tilt-sign: {e}; give 1 or -1"))?,
        ..sqscan::mock::rig::RigConfig::default()
    })
}

/// A duration of at most a day from the seconds a flag gives.
fn seconds(flag: &str, s: Option<f64>) -> Result<Option<Duration>> {
    s.map(|s| {
        Duration::try_from_secs_f64(s)
            .ok()
            .filter(|d| *d <= Duration::from_secs(86_400))
            .with_context(|| format!("{flag} {s}: give 0 to 86400 seconds"))
    })
    .transpose()
}

/// A device's path, with the link to it where one was asked for.
fn shown(path: &Path, link: &Option<PathBuf>) -> String {
    format!(
        "{}{}",
        path.display(),
        link.as_ref()
            .map(|l| format!(" (link {})", l.display()))
            .unwrap_or_default()
    )
}

/// Announces the replugged PTU, as the first one was.
async fn announce_replugged_ptu(mut replugged: tokio::sync::watch::Receiver<Option<PathBuf>>, link: Option<PathBuf>) {
    if replugged.wait_for(Option::is_some).await.is_ok()
        && let Some(path) = replugged.borrow().clone()
    {
        println!("mock rig: PTU plugged back in on {}", shown(&path, &link));
    }
}

/// What the rig's GigE Vision camera is made of, to plug it in (again).
struct CameraPlug {
    args: CameraArgs,
    scene: std::sync::Arc<sqscan::sim::Scene>,
    ptu: std::sync::Arc<std::sync::Mutex<dyn sqscan_drivers::mock::MockDevice>>,
    cfg: sqscan::mock::rig::RigConfig,
}

impl CameraPlug {
    /// Starts the camera: kept (returned) until the rig stops, or unplugged after
    /// `unplug_after` and plugged back in `replug_after` later by a task of its own.
    fn start(self, unplug_after: Option<Duration>, replug_after: Option<Duration>) -> Result<Option<Camera>> {
        let (columns, fraction_bits) = (self.scene.rig.sensor.columns, self.scene.rig.sensor.fraction_bits);
        let camera = start_camera_with(
            &self.args,
            self.scene.clone(),
            self.ptu.clone(),
            &self.cfg,
            columns,
            fraction_bits,
        )?;
        let Some(after) = unplug_after else {
            return Ok(Some(camera));
        };
        tokio::spawn(async move {
            tokio::time::sleep(after).await;
            unplug(camera);
            println!("mock rig: GigE Vision camera unplugged");
            let Some(again) = replug_after else { return };
            tokio::time::sleep(again).await;
            match start_camera_with(&self.args, self.scene, self.ptu, &self.cfg, columns, fraction_bits) {
                Ok(_camera) => {
                    println!("mock rig: GigE Vision camera plugged back in");
                    // Kept plugged in until the rig stops.
                    std::future::pending::<()>().await;
                }
                Err(e) => eprintln!("mock rig: cannot plug the camera back in: {e:#}"),
            }
        });
        Ok(None)
    }
}

/// Unplugs the camera: the emulator stops and closes its sockets.
fn unplug(_camera: Camera) {}

/// What starting the rig's camera needs of its arguments, on its own so a task can keep it.
#[derive(Clone)]
#[cfg_attr(not(feature = "gige"), allow(dead_code))]
struct CameraArgs {
    gige_address: String,
    rows_per_frame: u32,
    rate: f64,
    camera_clock_offset: f64,
    camera_clock_drift: f64,
}

impl MockRigArgs {
    fn clone_camera_args(&self) -> CameraArgs {
        CameraArgs {
            gige_address: self.gige_address.clone(),
            rows_per_frame: self.rows_per_frame,
            rate: self.rate,
            camera_clock_offset: self.camera_clock_offset,
            camera_clock_drift: self.camera_clock_drift,
        }
    }
}

#[cfg(feature = "gige")]
type Camera = sqscan_drivers::mock::gige::FakeLineCamera;
// Without GigE Vision there is no camera to hold: a value of this type cannot exist.
#[cfg(not(feature = "gige"))]
type Camera = std::convert::Infallible;

#[cfg(feature = "gige")]
fn start_camera_with(
    a: &CameraArgs,
    scene: std::sync::Arc<sqscan::sim::Scene>,
    ptu: std::sync::Arc<std::sync::Mutex<dyn sqscan_drivers::mock::MockDevice>>,
    cfg: &sqscan::mock::rig::RigConfig,
    columns: usize,
    fraction_bits: u8,
) -> Result<Camera> {
    use sqscan_drivers::mock::gige::FakeCameraConfig;
    let width = u32::try_from(columns).context("too many columns for a camera")?;
    let mut camera = FakeCameraConfig::new(a.gige_address.clone(), width);
    camera.rows_per_frame = a.rows_per_frame;
    camera.line_rate_hz = a.rate;
    camera.scale = 1.0 / f64::from(1u32 << fraction_bits);
    if !(a.camera_clock_offset.is_finite() && a.camera_clock_offset.abs() <= 1e9) {
        anyhow::bail!("--camera-clock-offset {}: give -1e9 to 1e9 s", a.camera_clock_offset);
    }
    if !(a.camera_clock_drift.is_finite() && a.camera_clock_drift.abs() <= 1e5) {
        anyhow::bail!("--camera-clock-drift {}: give -1e5 to 1e5 ppm", a.camera_clock_drift);
    }
    camera.clock = sqscan_drivers::mock::gige::CameraClock {
        offset_s: a.camera_clock_offset,
        drift_ppm: a.camera_clock_drift,
    };
    let c = sqscan::mock::rig::gige_camera(scene, ptu, cfg, &camera)
        .with_context(|| format!("cannot start the GigE Vision camera on {}", a.gige_address))?;
    println!(
        "mock rig: GigE Vision camera {} ({columns} columns, {} Hz, {} profiles a block) on {}",
        camera.serial, a.rate, a.rows_per_frame, a.gige_address
    );
    Ok(c)
}

#[cfg(not(feature = "gige"))]
fn start_camera_with(
    _: &CameraArgs,
    _: std::sync::Arc<sqscan::sim::Scene>,
    _: std::sync::Arc<std::sync::Mutex<dyn sqscan_drivers::mock::MockDevice>>,
    _: &sqscan::mock::rig::RigConfig,
    _: usize,
    _: u8,
) -> Result<Camera> {
    anyhow::bail!("--sensor gige: this sqscan was built without GigE Vision support (cargo feature gige)")
}

async fn mock_ptu(a: MockPtuArgs) -> Result<()> {
    let faults = a.faults.faults();
    let result = tokio::select! {
        r = serve_ptu(a.protocol, a.link.as_deref(), &faults, a.faults.replug_after_ms) => r,
        r = shutdown_signal() => r,
    };
    if let Some(link) = &a.link {
        // The link points at a pty that is gone now: leave no dangling device behind.
        let _ = std::fs::remove_file(link);
    }
    result
}

/// One mock unit after another: a new one is plugged in after each unplug if asked to.
async fn serve_ptu(kind: PtuKind, link: Option<&Path>, faults: &Faults, replug_after_ms: Option<u64>) -> Result<()> {
    loop {
        let port = MockPort::create(link).context("cannot create a pty")?;
        let unit = kind.mock();
        println!(
            "{} on {}{}",
            unit.description,
            port.path().display(),
            link.map(|l| format!(" (link {})", l.display())).unwrap_or_default()
        );
        match port
            .serve(unit.device, faults.clone())
            .await
            .context("mock PTU line failed")?
        {
            ServeEnd::Unplugged { replies } => {
                println!("unplugged after {replies} replies");
                let Some(ms) = replug_after_ms else {
                    return Ok(());
                };
                tokio::time::sleep(Duration::from_millis(ms)).await;
            }
        }
    }
}

/// Ctrl-C or SIGTERM (as from systemd or `kill`).
async fn shutdown_signal() -> Result<()> {
    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("cannot listen for SIGTERM")?;
    tokio::select! {
        r = tokio::signal::ctrl_c() => r.context("cannot listen for Ctrl-C")?,
        _ = term.recv() => {}
    }
    Ok(())
}
