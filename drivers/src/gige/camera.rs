//! A GigE Vision line-profile camera through aravis, as a [`ProfileSource`].
//!
//! aravis objects stay on one thread of their own (the grab thread): it opens the camera by
//! address, sets the configured features by name, reads what a block means (size, pixel format,
//! coordinate scale and offset, invalid value, line rate), then starts and stops acquisition on
//! command and decodes every block it receives into profiles ([`super::decode_block`]), each
//! stamped with the host's monotonic time of the block's arrival. The camera's own clock stamps
//! each row's exposure; the sweep assembler maps it onto the host's as it does for any sensor
//! (`sweep` module docs: the least-delayed profile).
//!
//! A camera that sends nothing while acquiring is asked for a register; when that fails too,
//! the camera is gone: [`Error::Disconnected`], and the thread ends. The owner reopens it.
//!
//! Over 600 lines on purpose: the camera's setup, its grab thread and the source
//! that serves its profiles share the thread's commands and the block counter.

#![allow(unsafe_code)]

use std::collections::VecDeque;
use std::sync::mpsc as std_mpsc;
use std::time::{Duration, Instant};

use aravis::prelude::*;
use aravis::{Buffer, BufferStatus, Camera};
use tokio::sync::{mpsc, oneshot};

use super::{BlockError, FeatureValue, RangeEncoding, RangePixel, RowTiming, StampedRow, decode_block};
use crate::Error;
use crate::profile::{SeqCounts, SequenceTracker};
use crate::sensor::{ProfileSource, ReceivedProfile};

/// How to open and set up the camera.
#[derive(Clone, Debug, PartialEq)]
pub struct GigeConfig {
    /// The camera's IP address (or an aravis device id). Opened directly, without discovery.
    pub address: String,
    /// Features set in this order after opening, e.g. `DeviceScanType = "Linescan3D"`.
    pub features: Vec<(String, FeatureValue)>,
    /// Profiles a block (`Height`); `None` keeps the camera's.
    pub rows_per_frame: Option<u32>,
    /// Fixed-point fraction bits of the profiles (the calibration's).
    pub fraction_bits: u8,
    /// Which row of a block its timestamp belongs to.
    pub stamped: StampedRow,
    /// Buffers queued for the stream.
    pub buffers: usize,
    /// Backward sequence steps up to this many are late blocks; beyond, a restart.
    pub reorder_window: u32,
}

impl GigeConfig {
    pub fn new(address: impl Into<String>) -> GigeConfig {
        GigeConfig {
            address: address.into(),
            features: Vec::new(),
            rows_per_frame: None,
            fraction_bits: 4,
            stamped: StampedRow::First,
            buffers: 16,
            reorder_window: SequenceTracker::DEFAULT_REORDER_WINDOW,
        }
    }
}

/// What the camera said about itself and its blocks once set up.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfo {
    pub vendor: String,
    pub model: String,
    pub serial: String,
    pub width: usize,
    pub rows_per_frame: usize,
    pub pixel_format: String,
    pub encoding: RangeEncoding,
    pub line_rate_hz: f64,
}

enum Command {
    Start(oneshot::Sender<Result<(), Error>>),
    Stop(oneshot::Sender<Result<(), Error>>),
}

type Block = Result<(Vec<crate::profile::Profile>, Instant), Error>;

/// An open GigE Vision line-profile camera.
pub struct GigeSensor {
    commands: std_mpsc::Sender<Command>,
    blocks: mpsc::UnboundedReceiver<Block>,
    pending: VecDeque<ReceivedProfile>,
    tracker: SequenceTracker,
    info: CameraInfo,
    /// The grab thread reported a failure (said once; then the camera is gone).
    failed: bool,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// How long a camera may send nothing while acquiring before its control channel is probed.
const SILENCE_PROBE: Duration = Duration::from_secs(1);
/// How long one wait for a buffer lasts on the grab thread (µs): commands are served between.
const POP_WAIT_US: u64 = 20_000;

fn camera_error(address: &str, what: &str, e: impl std::fmt::Display) -> Error {
    Error::Camera(format!("{address}: {what}: {e}"))
}

fn feature_error(feature: &str, e: impl std::fmt::Display) -> Error {
    Error::Feature {
        feature: feature.to_string(),
        message: e.to_string(),
    }
}

impl GigeSensor {
    /// Opens the camera at `cfg.address`, sets its features and reads what its blocks mean.
    /// Errors name the address, or the feature that could not be set or read.
    pub async fn open(cfg: GigeConfig) -> Result<GigeSensor, Error> {
        let (commands, command_rx) = std_mpsc::channel();
        let (block_tx, blocks) = mpsc::unbounded_channel();
        let (ready_tx, ready_rx) = oneshot::channel();
        let reorder_window = cfg.reorder_window;
        let thread = std::thread::Builder::new()
            .name("gige-grab".into())
            .spawn(move || grab_thread(cfg, command_rx, block_tx, ready_tx))
            .map_err(Error::Io)?;
        let info = ready_rx
            .await
            .map_err(|_| Error::Camera("the grab thread ended while opening".into()))??;
        Ok(GigeSensor {
            commands,
            blocks,
            pending: VecDeque::new(),
            tracker: SequenceTracker::new(reorder_window),
            info,
            failed: false,
            thread: Some(thread),
        })
    }

    /// Closes the camera and waits until it is released (its control channel given up), so
    /// that another client can take it at once. Dropping the sensor releases it too, but in the
    /// background: a process that exits right after may leave the camera to time out its
    /// heartbeat first (a few seconds).
    pub fn close(self) {
        let GigeSensor { commands, thread, .. } = self;
        drop(commands);
        if let Some(t) = thread {
            let _ = t.join();
        }
    }

    pub fn info(&self) -> &CameraInfo {
        &self.info
    }

    /// Sequence totals over the profiles handed out.
    pub fn counts(&self) -> SeqCounts {
        self.tracker.counts()
    }

    async fn command(&mut self, make: impl FnOnce(oneshot::Sender<Result<(), Error>>) -> Command) -> Result<(), Error> {
        let (tx, rx) = oneshot::channel();
        self.commands.send(make(tx)).map_err(|_| Error::Disconnected)?;
        match tokio::time::timeout(Duration::from_secs(15), rx).await {
            Ok(Ok(r)) => r,
            Ok(Err(_)) => Err(Error::Disconnected),
            Err(_) => Err(Error::Timeout {
                waiting_for: "the camera to answer a command",
                after: Duration::from_secs(15),
            }),
        }
    }
}

impl ProfileSource for GigeSensor {
    async fn start(&mut self) -> Result<(), Error> {
        self.command(Command::Start).await
    }

    async fn stop(&mut self) -> Result<(), Error> {
        self.command(Command::Stop).await
    }

    async fn next_profile(&mut self, wait: Duration) -> Result<ReceivedProfile, Error> {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            if let Some(p) = self.pending.pop_front() {
                return Ok(p);
            }
            if self.failed {
                return Err(Error::Disconnected);
            }
            match tokio::time::timeout_at(deadline, self.blocks.recv()).await {
                Err(_) => {
                    return Err(Error::Timeout {
                        waiting_for: "a profile",
                        after: wait,
                    });
                }
                Ok(None) => self.failed = true,
                Ok(Some(Err(e))) => {
                    self.failed = true;
                    return Err(e);
                }
                Ok(Some(Ok((profiles, received)))) => {
                    for profile in profiles {
                        let seq = self.tracker.observe(profile.seq);
                        self.pending.push_back(ReceivedProfile { profile, received, seq });
                    }
                }
            }
        }
    }
}

/// A GigE Vision device that answered discovery.
#[derive(Clone, Debug, PartialEq)]
pub struct Discovered {
    /// aravis's device id (vendor-model-serial).
    pub id: String,
    pub vendor: String,
    pub model: String,
    /// The address to open it by.
    pub address: String,
}

/// The GigE Vision devices that answer a discovery broadcast on the host's interfaces. The
/// broadcast goes to every interface's network: run it where that is meant (on a robot's
/// camera network, or in a private network namespace). Other transports aravis knows (USB3
/// Vision, its own in-process fake) are left out.
pub fn discover() -> Vec<Discovered> {
    // SAFETY: aravis's device list is global state; `get_device_list` updates and reads it in
    // one call, and this crate makes no other use of it.
    let all = unsafe { aravis::get_device_list() };
    all.into_iter()
        .filter(|d| d.protocol.to_string_lossy() == "GigEVision")
        .map(|d| Discovered {
            id: d.id.to_string_lossy().into_owned(),
            vendor: d.vendor.to_string_lossy().into_owned(),
            model: d.model.to_string_lossy().into_owned(),
            address: d.address.to_string_lossy().into_owned(),
        })
        .collect()
}

/// Opens the camera and sets the configured features, and the rows a block when given.
fn open_with_features(cfg: &GigeConfig) -> Result<Camera, Error> {
    let address = cfg.address.as_str();
    let cam = Camera::new(Some(address)).map_err(|e| camera_error(address, "cannot open the GigE Vision camera", e))?;
    for (name, value) in &cfg.features {
        let r = match value {
            FeatureValue::Bool(b) => cam.set_boolean(name, *b),
            FeatureValue::Int(i) => cam.set_integer(name, *i),
            FeatureValue::Float(x) => cam.set_float(name, *x),
            FeatureValue::Str(s) => cam.set_string(name, s),
        };
        r.map_err(|e| feature_error(name, format!("cannot set it to {value}: {e}")))?;
    }
    if let Some(h) = cfg.rows_per_frame {
        cam.set_integer("Height", i64::from(h))
            .map_err(|e| feature_error("Height", format!("cannot set {h} rows a frame: {e}")))?;
    }
    Ok(cam)
}

/// Opens the camera with the configured features set, then reads what a block means from it;
/// the `Result` says why not.
fn setup(cfg: &GigeConfig) -> Result<(Camera, CameraInfo), Error> {
    let address = cfg.address.as_str();
    let cam = open_with_features(cfg)?;
    let device = cam
        .device()
        .ok_or_else(|| camera_error(address, "no device behind the camera", "aravis gave none"))?;
    let has = |name: &str| device.feature(name).is_some();
    let int = |name: &str| cam.integer(name).map_err(|e| feature_error(name, e));
    let float = |name: &str| cam.float(name).map_err(|e| feature_error(name, e));
    let string = |name: &str| {
        if has(name) {
            cam.string(name).map(|s| s.to_string()).unwrap_or_default()
        } else {
            String::new()
        }
    };
    let width = int("Width")?;
    let height = int("Height")?;
    let (width, height) = match (usize::try_from(width), usize::try_from(height)) {
        (Ok(w), Ok(h)) if (1..=usize::from(u16::MAX)).contains(&w) && h >= 1 => (w, h),
        _ => {
            return Err(feature_error(
                "Width",
                format!("{width} x {height}: a block needs 1 to 65535 columns and at least one row"),
            ));
        }
    };
    let pixel_format = cam
        .string("PixelFormat")
        .map_err(|e| feature_error("PixelFormat", e))?
        .to_string();
    let pixel = RangePixel::from_name(&pixel_format).ok_or_else(|| {
        feature_error(
            "PixelFormat",
            format!("{pixel_format}: not a range format; set Coord3D_C16, Coord3D_C12p or Mono16"),
        )
    })?;
    let scale = if has("Scan3dCoordinateScale") {
        float("Scan3dCoordinateScale")?
    } else {
        1.0
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(feature_error(
            "Scan3dCoordinateScale",
            format!("{scale}: not a positive number"),
        ));
    }
    let offset = if has("Scan3dCoordinateOffset") {
        float("Scan3dCoordinateOffset")?
    } else {
        0.0
    };
    let flagged = !has("Scan3dInvalidDataFlag")
        || cam
            .boolean("Scan3dInvalidDataFlag")
            .map_err(|e| feature_error("Scan3dInvalidDataFlag", e))?;
    let invalid = if flagged && has("Scan3dInvalidDataValue") {
        Some(float("Scan3dInvalidDataValue")?)
    } else {
        None
    };
    let line_rate_hz = float("AcquisitionLineRate")?;
    if !(line_rate_hz.is_finite() && line_rate_hz > 0.0) {
        return Err(feature_error(
            "AcquisitionLineRate",
            format!("{line_rate_hz}: not a rate"),
        ));
    }
    let info = CameraInfo {
        vendor: string("DeviceVendorName"),
        model: string("DeviceModelName"),
        serial: string("DeviceSerialNumber"),
        width,
        rows_per_frame: height,
        pixel_format,
        encoding: RangeEncoding {
            pixel,
            scale,
            offset,
            invalid,
            fraction_bits: cfg.fraction_bits,
        },
        line_rate_hz,
    };
    Ok((cam, info))
}

/// Unwraps block ids into a running block count: GigE Vision 1.x ids are 16 bits and skip 0
/// (65535 is followed by 1); 2.x ids are 64 bits. A step back (a late block, a camera that
/// restarted its count) moves the count back by as much, so the sequence numbers show it to the
/// tracker as late or as a restart.
#[derive(Default)]
struct BlockCounter {
    last: Option<u64>,
    count: u64,
}

impl BlockCounter {
    fn next(&mut self, id: u64) -> u64 {
        if let Some(last) = self.last {
            let forward = if id >= last {
                id - last
            } else if last <= 0xFFFF && last - id > 0x8000 {
                // A 16-bit wrap: 65535 -> 1 is one step.
                id + 0xFFFF - last
            } else {
                self.count = self.count.wrapping_sub(last - id);
                self.last = Some(id);
                return self.count;
            };
            self.count = self.count.wrapping_add(forward);
        }
        self.last = Some(id);
        self.count
    }
}

fn grab_thread(
    cfg: GigeConfig,
    commands: std_mpsc::Receiver<Command>,
    blocks: mpsc::UnboundedSender<Block>,
    ready: oneshot::Sender<Result<CameraInfo, Error>>,
) {
    let (cam, info, stream) = match open_stream(&cfg) {
        Ok(v) => v,
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    let mut grab = Grabber {
        address: cfg.address.clone(),
        stamped: cfg.stamped,
        line_period_ns: 1e9 / info.line_rate_hz,
        width: info.width,
        height: info.rows_per_frame,
        enc: info.encoding,
        cam,
        acquiring: false,
        counter: BlockCounter::default(),
        failed_blocks: 0,
        last_block: Instant::now(),
    };
    if ready.send(Ok(info)).is_err() {
        return;
    }
    loop {
        let command = if grab.acquiring {
            commands
                .try_recv()
                .map_err(|e| matches!(e, std_mpsc::TryRecvError::Disconnected))
        } else {
            commands
                .recv_timeout(Duration::from_millis(100))
                .map_err(|e| matches!(e, std_mpsc::RecvTimeoutError::Disconnected))
        };
        match command {
            Ok(c) => grab.obey(c),
            // The owner is gone: leave the camera quiet.
            Err(true) => {
                if grab.acquiring {
                    let _ = grab.cam.stop_acquisition();
                }
                return;
            }
            Err(false) => {}
        }
        if !grab.acquiring {
            continue;
        }
        let Some(buffer) = stream.timeout_pop_buffer(POP_WAIT_US) else {
            if grab.last_block.elapsed() > SILENCE_PROBE {
                // Nothing for a while: is the camera still there? A register read fails
                // after GVCP's retries when it is not.
                if let Err(e) = grab.cam.integer("Width") {
                    tracing::warn!("{}: the camera stopped answering: {e}", grab.address);
                    let _ = blocks.send(Err(Error::Disconnected));
                    return;
                }
                grab.last_block = Instant::now();
            }
            continue;
        };
        let delivered = grab.take(&buffer, &blocks);
        stream.push_buffer(buffer);
        if !delivered {
            let _ = grab.cam.stop_acquisition();
            return;
        }
    }
}

/// The camera set up as `cfg` asks, and its stream with `cfg.buffers` buffers of one block's
/// payload each.
fn open_stream(cfg: &GigeConfig) -> Result<(Camera, CameraInfo, aravis::Stream), Error> {
    let (cam, info) = setup(cfg)?;
    let stream = cam
        .create_stream()
        .map_err(|e| camera_error(&cfg.address, "cannot open a stream", e))?;
    // A block's payload holds its pixels, and perhaps padding or chunks; not gigabytes more.
    let need = info
        .encoding
        .pixel
        .bytes(info.width * info.rows_per_frame)
        .unwrap_or(usize::MAX);
    let payload = match cam.payload() {
        Ok(p) if (p as usize) >= need && (p as usize) <= need.saturating_mul(2).saturating_add(1 << 16) => p as usize,
        Ok(p) => {
            return Err(feature_error(
                "PayloadSize",
                format!("{p} bytes for a block of {need}: the camera's size features disagree"),
            ));
        }
        Err(e) => return Err(feature_error("PayloadSize", e)),
    };
    for _ in 0..cfg.buffers.max(2) {
        stream.push_buffer(Buffer::new_allocate(payload));
    }
    Ok((cam, info, stream))
}

/// The grab thread's camera and what it keeps between blocks.
struct Grabber {
    address: String,
    stamped: StampedRow,
    line_period_ns: f64,
    width: usize,
    height: usize,
    enc: RangeEncoding,
    cam: Camera,
    acquiring: bool,
    counter: BlockCounter,
    failed_blocks: u64,
    /// When the last good block came (or acquisition started, or the camera last answered).
    last_block: Instant,
}

impl Grabber {
    fn obey(&mut self, command: Command) {
        match command {
            Command::Start(reply) => {
                let r = self
                    .cam
                    .start_acquisition()
                    .map_err(|e| camera_error(&self.address, "cannot start acquisition", e));
                self.acquiring |= r.is_ok();
                self.counter = BlockCounter::default();
                self.last_block = Instant::now();
                let _ = reply.send(r);
            }
            Command::Stop(reply) => {
                self.acquiring = false;
                let _ = reply.send(
                    self.cam
                        .stop_acquisition()
                        .map_err(|e| camera_error(&self.address, "cannot stop acquisition", e)),
                );
            }
        }
    }

    /// One buffer from the stream: a good block decoded and sent on; a failed, misshapen or
    /// undecodable one said and skipped. False when nobody takes the blocks any more.
    fn take(&mut self, buffer: &Buffer, blocks: &mpsc::UnboundedSender<Block>) -> bool {
        let received = Instant::now();
        let status = buffer.status();
        let shape = (buffer.image_width(), buffer.image_height(), buffer.image_pixel_format());
        let expected = (self.width as i32, self.height as i32);
        if status != BufferStatus::Success {
            // Incomplete or lost blocks (a packet size over the path's MTU, a full link): said,
            // and the camera is not alive for them.
            self.failed_blocks += 1;
            if self.failed_blocks.is_power_of_two() {
                tracing::warn!(
                    "{}: {} blocks failed, the last {status:?}",
                    self.address,
                    self.failed_blocks
                );
            }
            return true;
        }
        if (shape.0, shape.1) != expected || RangePixel::from_pfnc(shape.2.raw()) != Some(self.enc.pixel) {
            tracing::warn!(
                "{}: a block of {} x {} {:?} where {} x {} {:?} was set up: skipped",
                self.address,
                shape.0,
                shape.1,
                shape.2,
                self.width,
                self.height,
                self.enc.pixel
            );
            return true;
        }
        self.last_block = received;
        let block = self.counter.next(buffer.frame_id());
        let (ptr, len) = buffer.data();
        let bytes: &[u8] = if ptr.is_null() || len == 0 {
            &[]
        } else {
            // SAFETY: aravis hands out the buffer's own data and its length; the buffer is
            // alive (borrowed here) and not pushed back to the stream until `bytes` is dead.
            unsafe { std::slice::from_raw_parts(ptr, len) }
        };
        let timing = RowTiming {
            block_ns: buffer.timestamp(),
            line_period_ns: self.line_period_ns,
            stamped: self.stamped,
        };
        let first_seq = (block.wrapping_mul(self.height as u64)) as u32;
        let decoded = decode_block(bytes, self.width, self.height, &self.enc, &timing, first_seq)
            .map_err(|e: BlockError| Error::Camera(format!("{}: block {}: {e}", self.address, buffer.frame_id())));
        match decoded {
            Ok(profiles) => return blocks.send(Ok((profiles, received))).is_ok(),
            // A block that does not decode is lost, as a corrupt SQPF frame is: its sequence
            // numbers show as missing.
            Err(e) => tracing::warn!("{e}"),
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_ids_unwrap_past_their_sixteen_bits() {
        let mut c = BlockCounter::default();
        assert_eq!(c.next(65_534), 0);
        assert_eq!(c.next(65_535), 1);
        // 0 is never used: 65535 is followed by 1.
        assert_eq!(c.next(1), 2);
        // A lost block shows as a step of two.
        assert_eq!(c.next(3), 4);
        assert_eq!(c.next(3), 4);
        // A late block steps back, and the next one forward again.
        assert_eq!(c.next(2), 3);
        assert_eq!(c.next(4), 5);
        // 64-bit ids count on past 16 bits.
        let mut c = BlockCounter::default();
        assert_eq!(c.next(65_535), 0);
        assert_eq!(c.next(65_536), 1);
        assert_eq!(c.next(70_000), 70_000 - 65_535);
    }
}
