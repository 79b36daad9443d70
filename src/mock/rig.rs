//! The mock scanning rig: one mock PTU and one mock profile sensor, each on its own pty, sharing
//! one simulated world.
//!
//! The PTU is a `sqscan_drivers` mock (PowerCube or PTU-D46) served as usual; the sensor renders
//! the scene with [`sim::render_profile`] at the PTU's angles *at the moment of exposure*
//! ([`MockDevice::joint_angles`] on the same device, behind the same mutex), so a profile taken
//! while the unit moves sees the world from where the unit is then. Profiles are stamped with the
//! sensor's own clock (monotonic ns since the rig started) and sent as SQPF frames while the
//! host has sent `START`.
//!
//! Fault tests: `RigConfig::ptu_faults.disconnect_after` unplugs the PTU mid-sweep (its pty
//! closes); with `RigConfig::ptu_replug_after` the same unit comes back later on a new pty, the
//! PTU link re-pointed at it, while the sensor streams on throughout.
//!
//! Device angles map to the joint angles the scene's rig uses through `RigConfig::pan_axis` and
//! `tilt_axis` (how the unit is mounted): identity by default, which is what
//! [`crate::sim::Rig::calibration`] and `calibration/sim_rig.toml` assume. A PTU-D46
//! tilts down at negative positions, and its tilt range (-47..+31 deg) holds a downward sweep only
//! that way round: `tilt_axis` sign -1 with `calibration/sim_rig_flir.toml`.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sqscan_drivers::mock::{Faults, MockDevice, MockPort, ServeEnd};
use sqscan_drivers::profile::Profile;
use sqscan_drivers::{AxisConfig, PtuKind};
use tokio::sync::watch;
use tokio::task::JoinHandle;

use crate::numeric::stream_seed;
use crate::sim::{self, Scene};

/// How the rig runs.
#[derive(Clone, Debug)]
pub struct RigConfig {
    /// Which PTU the rig carries (its mock from the kind table).
    pub ptu_kind: PtuKind,
    /// Profiles a second while acquiring.
    pub rate_hz: f64,
    /// Seed of the sensor noise: profile `i` uses `stream_seed(seed, i)`.
    pub seed: u64,
    pub ptu_faults: Faults,
    pub sensor_faults: Faults,
    /// After the PTU's `ptu_faults.disconnect_after` unplug, plug it back in this much later:
    /// a new pty, the PTU link symlink re-pointed at it, the same device (same angles, same
    /// move) served again, once, without the unplug fault. The sensor streams on meanwhile.
    pub ptu_replug_after: Option<Duration>,
    /// Device to joint angle, per axis, as the unit is mounted on the rig.
    pub pan_axis: AxisConfig,
    pub tilt_axis: AxisConfig,
}

impl Default for RigConfig {
    fn default() -> Self {
        Self {
            ptu_kind: PtuKind::PowerCube,
            rate_hz: 50.0,
            seed: 1,
            ptu_faults: Faults::default(),
            sensor_faults: Faults::default(),
            ptu_replug_after: None,
            pan_axis: AxisConfig::default(),
            tilt_axis: AxisConfig::default(),
        }
    }
}

/// A running rig. Dropping it leaves the tasks running; [`RigMock::shutdown`] unplugs both.
pub struct RigMock {
    pub ptu_path: PathBuf,
    pub sensor_path: PathBuf,
    /// The PTU's device side, e.g. to read where it really is.
    pub ptu: Arc<Mutex<dyn MockDevice>>,
    /// Serves the PTU; with [`RigConfig::ptu_replug_after`] it goes on after the unplug, and
    /// ends with how the second line ended.
    pub ptu_task: JoinHandle<io::Result<ServeEnd>>,
    pub sensor_task: JoinHandle<io::Result<ServeEnd>>,
    /// The PTU's new pty path once it has been plugged back in (`None` until then). With a
    /// PTU link, the link points there too.
    pub ptu_replugged: watch::Receiver<Option<PathBuf>>,
}

impl RigMock {
    /// Starts the rig on the current tokio runtime: two ptys (with symlinks at the given links),
    /// the PTU answering on one, the sensor streaming on the other once started.
    pub fn start(
        scene: Arc<Scene>,
        cfg: &RigConfig,
        ptu_link: Option<&Path>,
        sensor_link: Option<&Path>,
    ) -> io::Result<RigMock> {
        if !(cfg.rate_hz.is_finite() && cfg.rate_hz > 0.0 && cfg.rate_hz <= 10_000.0) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("rate {} Hz: give (0, 10000]", cfg.rate_hz),
            ));
        }
        let ptu = cfg.ptu_kind.mock().device;
        let ptu_port = MockPort::create(ptu_link)?;
        let sensor_port = MockPort::create(sensor_link)?;
        let (ptu_path, sensor_path) = (ptu_port.path().to_owned(), sensor_port.path().to_owned());
        let (replugged_tx, ptu_replugged) = watch::channel(None);
        let ptu_task = tokio::spawn(serve_ptu(
            ptu_port,
            ptu.clone(),
            cfg.ptu_faults.clone(),
            cfg.ptu_replug_after,
            replugged_tx,
        ));
        let source = scene_source(scene, ptu.clone(), cfg.seed, (cfg.pan_axis, cfg.tilt_axis));
        let period = Duration::from_secs_f64(1.0 / cfg.rate_hz);
        let sensor_task = tokio::spawn(sensor_port.stream(source, period, cfg.sensor_faults.clone()));
        Ok(RigMock {
            ptu_path,
            sensor_path,
            ptu,
            ptu_task,
            sensor_task,
            ptu_replugged,
        })
    }

    /// Unplugs both devices (their ptys close).
    pub fn shutdown(self) {
        self.ptu_task.abort();
        self.sensor_task.abort();
    }
}

/// Serves the PTU until unplugged; then, if asked to, once more on a new pty at the same link.
async fn serve_ptu(
    port: MockPort,
    device: Arc<Mutex<dyn MockDevice>>,
    faults: Faults,
    replug_after: Option<Duration>,
    replugged: watch::Sender<Option<PathBuf>>,
) -> io::Result<ServeEnd> {
    let link = port.link().map(Path::to_owned);
    let end = port.serve(device.clone(), faults.clone()).await?;
    let Some(after) = replug_after else {
        return Ok(end);
    };
    // `serve` consumed the port: the old pty is closed, the driver sees the unplug.
    tokio::time::sleep(after).await;
    let port = MockPort::create(link.as_deref())?;
    tracing::info!(path = %port.path().display(), "mock rig: PTU plugged back in");
    let _ = replugged.send(Some(port.path().to_owned()));
    // Once: the fault counter does not unplug it again.
    let faults = Faults {
        disconnect_after: None,
        ..faults
    };
    port.serve(device, faults).await
}

/// The profile the sensor sees with the unit at device angles `(pan, tilt)`, its noise from
/// `seed`.
fn render_at(
    scene: &Scene,
    (pan, tilt): (f64, f64),
    (pan_axis, tilt_axis): (AxisConfig, AxisConfig),
    seed: u64,
) -> sim::RawProfile {
    let pose = scene
        .rig
        .sensor_in_base(pan_axis.to_joint(pan), tilt_axis.to_joint(tilt));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    sim::render_profile(scene, &pose, &mut rng)
}

/// The sensor's view: the scene rendered at the PTU's angles at `now`.
fn scene_source(
    scene: Arc<Scene>,
    ptu: Arc<Mutex<dyn MockDevice>>,
    seed: u64,
    (pan_axis, tilt_axis): (AxisConfig, AxisConfig),
) -> impl FnMut(Instant) -> Profile + Send {
    let mut index = 0u64;
    move |now| {
        let (pan, tilt) = ptu.lock().unwrap_or_else(|p| p.into_inner()).joint_angles(now);
        let raw = render_at(&scene, (pan, tilt), (pan_axis, tilt_axis), stream_seed(seed, index));
        index += 1;
        Profile {
            seq: 0,
            timestamp_ns: 0,
            fraction_bits: scene.rig.sensor.fraction_bits,
            rows: raw.rows,
            intensity: Some(raw.intensity),
        }
    }
}

/// The rig's sensor as a GigE Vision line-profile camera: aravis's camera emulator on
/// `address` serving blocks of `rows_per_frame` profiles at `rate_hz`, each profile the scene
/// rendered at the PTU's angles when it was exposed. A block is sent after its last row, so its
/// rows lie in the past when rendered: the PTU's angles are sampled every 2 ms into a history
/// that the rows are interpolated from. Runs until the returned camera is dropped; the sampler
/// stops with it.
#[cfg(feature = "gige")]
pub fn gige_camera(
    scene: Arc<Scene>,
    ptu: Arc<Mutex<dyn MockDevice>>,
    cfg: &RigConfig,
    camera: &sqscan_drivers::mock::gige::FakeCameraConfig,
) -> Result<sqscan_drivers::mock::gige::FakeLineCamera, sqscan_drivers::Error> {
    use sqscan_drivers::mock::gige::FakeLineCamera;
    use std::collections::VecDeque;

    const KEEP: Duration = Duration::from_secs(5);
    type History = Arc<Mutex<VecDeque<(Instant, f64, f64)>>>;
    let history: History = Arc::new(Mutex::new(VecDeque::new()));
    let sample = {
        let (ptu, history) = (ptu.clone(), history.clone());
        move || {
            let now = Instant::now();
            let (pan, tilt) = ptu.lock().unwrap_or_else(|p| p.into_inner()).joint_angles(now);
            let mut h = history.lock().unwrap_or_else(|p| p.into_inner());
            h.push_back((now, pan, tilt));
            while h.front().is_some_and(|f| now.duration_since(f.0) > KEEP) {
                h.pop_front();
            }
        }
    };
    sample();
    // A thread, not a task: the camera's rows need the history whether or not a runtime runs.
    let alive = Arc::new(());
    let watch = Arc::downgrade(&alive);
    std::thread::Builder::new()
        .name("rig-ptu-history".into())
        .spawn(move || {
            while watch.upgrade().is_some() {
                sample();
                std::thread::sleep(Duration::from_millis(2));
            }
        })
        .map_err(sqscan_drivers::Error::Io)?;
    let angles_at = move |t: Instant| -> (f64, f64) {
        let h = history.lock().unwrap_or_else(|p| p.into_inner());
        let after = h.partition_point(|s| s.0 <= t);
        match (after.checked_sub(1).and_then(|i| h.get(i)), h.get(after)) {
            (Some(a), Some(b)) => {
                let span = b.0.duration_since(a.0).as_secs_f64();
                let w = if span > 0.0 {
                    t.duration_since(a.0).as_secs_f64() / span
                } else {
                    0.0
                };
                (a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2))
            }
            (Some(a), None) => (a.1, a.2),
            (None, Some(b)) => (b.1, b.2),
            (None, None) => (0.0, 0.0),
        }
    };
    let (pan_axis, tilt_axis, seed) = (cfg.pan_axis, cfg.tilt_axis, cfg.seed);
    let unit = f64::from(1u32 << scene.rig.sensor.fraction_bits);
    let mut index = 0u64;
    let source = move |exposed: Instant, rows: &mut [f64]| {
        let _alive = &alive;
        let raw = render_at(
            &scene,
            angles_at(exposed),
            (pan_axis, tilt_axis),
            stream_seed(seed, index),
        );
        index += 1;
        for (out, r) in rows.iter_mut().zip(&raw.rows) {
            *out = if *r == 0 { f64::NAN } else { f64::from(*r) / unit };
        }
    };
    FakeLineCamera::start(camera, Box::new(source))
}
