//! A mock GigE Vision line-profile camera: aravis's camera emulator (`ArvGvFakeCamera`, the
//! real GVCP control and GVSP stream protocols on a network interface) with our GenICam
//! description (`line_profile_camera.xml`: the Ranger3-class 3D features) and our own frames.
//!
//! The camera exposes one profile every line period, continuously while acquiring, and sends a
//! block when its last row is exposed. The emulator asks for frames more often than that; [`fill`]
//! waits until the block's last row is due (the emulator's thread then sends it), asks the
//! [`RowSource`] for the sub-pixel row of every column of every profile of the block, each at
//! the host time that profile was exposed, encodes
//! them with the coordinate scale, offset and invalid value that the camera's registers hold at
//! that moment, and stamps the block with the first row's exposure on the camera's own clock
//! ([`CameraClock`]: an offset and a drift against the host's). So a client that sets a feature
//! by name changes what the next frame carries, as on a camera.
//!
//! This is the device side, written apart from the client (`gige::camera`): the two meet only
//! through the protocol, so each checks the other.

#![allow(unsafe_code)]

use std::ffi::c_void;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use aravis::{FakeCamera, GvFakeCamera};

use crate::Error;

/// The GenICam description the emulator serves.
pub const GENICAM_XML: &str = include_str!("line_profile_camera.xml");

// Registers of the 3D features (line_profile_camera.xml) and of the emulator itself.
const REG_WIDTH: u32 = 0x100;
const REG_HEIGHT: u32 = 0x104;
const REG_PIXEL_FORMAT: u32 = 0x128;
const REG_FRAME_PERIOD_US: u32 = 0x138;
const REG_SCAN_TYPE: u32 = 0x4000;
const REG_SCALE: u32 = 0x4010;
const REG_OFFSET: u32 = 0x4018;
const REG_INVALID_FLAG: u32 = 0x4020;
const REG_INVALID_VALUE: u32 = 0x4028;
const REG_LINE_RATE: u32 = 0x4030;
/// `DeviceScanType = Linescan3D`.
const LINESCAN_3D: u32 = 1;

/// What the camera sees: the sub-pixel row of each column (NaN: no return) for a profile
/// exposed at `exposed`.
pub trait RowSource: Send {
    fn row(&mut self, exposed: Instant, rows: &mut [f64]);
}

impl<F: FnMut(Instant, &mut [f64]) + Send> RowSource for F {
    fn row(&mut self, exposed: Instant, rows: &mut [f64]) {
        self(exposed, rows)
    }
}

/// The camera's clock against the host's: `camera_ns = (host_s * (1 + drift_ppm / 1e6) +
/// offset_s) * 1e9`, host seconds counted from when the camera started.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraClock {
    pub offset_s: f64,
    pub drift_ppm: f64,
}

impl Default for CameraClock {
    fn default() -> Self {
        // A camera's clock counts from its own power-up: far from the host's.
        CameraClock {
            offset_s: 1234.5,
            drift_ppm: 0.0,
        }
    }
}

/// How the mock camera starts.
#[derive(Clone, Debug, PartialEq)]
pub struct FakeCameraConfig {
    /// The interface address to serve on (the emulator binds GVCP port 3956 there).
    pub address: String,
    pub serial: String,
    /// Columns a profile (`Width`, `SensorWidth`).
    pub width: u32,
    /// Profiles a block (`Height`).
    pub rows_per_frame: u32,
    /// `AcquisitionLineRate` (profiles a second).
    pub line_rate_hz: f64,
    /// `Scan3dCoordinateScale` and `Scan3dCoordinateOffset`: a pixel is (row - offset) / scale.
    pub scale: f64,
    pub offset: f64,
    /// `Scan3dInvalidDataValue`: the pixel of a column without a return.
    pub invalid_value: f64,
    pub clock: CameraClock,
}

impl FakeCameraConfig {
    pub fn new(address: impl Into<String>, width: u32) -> FakeCameraConfig {
        FakeCameraConfig {
            address: address.into(),
            serial: "SQ-LP-0001".into(),
            width,
            rows_per_frame: 10,
            line_rate_hz: 60.0,
            scale: 1.0 / 16.0,
            offset: 0.0,
            invalid_value: 0.0,
            clock: CameraClock::default(),
        }
    }
}

pub use super::netns::in_private_network;

/// What the fill callback works with; lives until the emulator is gone.
struct State {
    camera: Mutex<FakeCamera>,
    source: Mutex<Box<dyn RowSource>>,
    clock: CameraClock,
    epoch: Instant,
    /// When the next profile is exposed; `None` until acquisition runs.
    next_row: Mutex<Option<Instant>>,
}

/// aravis's own camera emulator with aravis's stock description (what `arv-fake-gv-camera`
/// serves): a 2D camera with none of the line-profile features (no `DeviceScanType`, no
/// `AcquisitionLineRate`), for checking that such a camera is refused by name. Serves until
/// dropped.
pub struct StockFakeCamera {
    _emulator: GvFakeCamera,
}

impl StockFakeCamera {
    pub fn start(address: &str) -> Result<StockFakeCamera, Error> {
        let emulator = GvFakeCamera::new_full(Some(address), Some("GV01"), None);
        if !emulator.is_running() {
            return Err(Error::Camera(format!(
                "stock mock at {address}: the emulator did not start (is the address on an interface, and port 3956 free?)"
            )));
        }
        Ok(StockFakeCamera { _emulator: emulator })
    }
}

/// A running mock camera. Dropping it unplugs it: the emulator stops and closes its sockets.
pub struct FakeLineCamera {
    emulator: Option<GvFakeCamera>,
    state: *mut State,
    fake: *mut aravis_sys::ArvFakeCamera,
}

// SAFETY: `state` is only read through a shared reference (its fields are behind mutexes) by
// the emulator's thread and freed in `drop` after the emulator is gone; `GvFakeCamera` is Send.
unsafe impl Send for FakeLineCamera {}

fn write_f64(camera: &FakeCamera, address: u32, value: f64) {
    let bits = value.to_bits();
    camera.write_register(address, (bits >> 32) as u32);
    camera.write_register(address + 4, bits as u32);
}

/// A string register of `len` bytes (NUL-padded), four bytes a register write (each stored
/// big-endian, so the bytes land in order).
fn write_string(camera: &FakeCamera, address: u32, len: u32, text: &str) {
    let mut bytes = text.as_bytes().to_vec();
    bytes.resize(len as usize, 0);
    for (k, word) in bytes.chunks(4).enumerate() {
        let mut b = [0u8; 4];
        b[..word.len()].copy_from_slice(word);
        camera.write_register(address + 4 * k as u32, u32::from_be_bytes(b));
    }
}

fn read_f64(camera: &FakeCamera, address: u32) -> f64 {
    let hi = camera.read_register(address).unwrap_or(0);
    let lo = camera.read_register(address + 4).unwrap_or(0);
    f64::from_bits((u64::from(hi) << 32) | u64::from(lo))
}

impl FakeLineCamera {
    /// Serves the camera on `cfg.address` until dropped.
    pub fn start(cfg: &FakeCameraConfig, source: Box<dyn RowSource>) -> Result<FakeLineCamera, Error> {
        let bad = |what: String| Err(Error::Camera(format!("mock at {}: {what}", cfg.address)));
        if !(cfg.line_rate_hz.is_finite() && cfg.line_rate_hz > 0.0 && cfg.line_rate_hz <= 100_000.0) {
            return bad(format!("line rate {} Hz: give (0, 100000]", cfg.line_rate_hz));
        }
        if !(cfg.scale.is_finite() && cfg.scale > 0.0) {
            return bad(format!("coordinate scale {}: give a positive number", cfg.scale));
        }
        if !(1..=4096).contains(&cfg.width) || !(1..=4096).contains(&cfg.rows_per_frame) {
            return bad(format!("{} x {}: give 1 to 4096 each", cfg.width, cfg.rows_per_frame));
        }
        // The emulator answers its control channel on the thread that fills the blocks: a block
        // must not take longer than a control exchange may wait.
        if f64::from(cfg.rows_per_frame) / cfg.line_rate_hz > MAX_BLOCK_S {
            return bad(format!(
                "{} profiles a block at {} Hz take over {MAX_BLOCK_S} s",
                cfg.rows_per_frame, cfg.line_rate_hz
            ));
        }
        // The emulator reads its description from a file.
        let xml = std::env::temp_dir().join(format!(
            "sqscan-line-profile-camera-{}-{}.xml",
            std::process::id(),
            cfg.serial
        ));
        std::fs::write(&xml, GENICAM_XML).map_err(Error::Io)?;
        let emulator = GvFakeCamera::new_full(Some(&cfg.address), Some(&cfg.serial), xml.to_str());
        let _ = std::fs::remove_file(&xml);
        if !emulator.is_running() {
            return bad("the emulator did not start (is the address on an interface, and port 3956 free?)".into());
        }
        let Some(camera) = emulator.fake_camera() else {
            return bad("the emulator has no camera".into());
        };
        // Our names where the emulator put its own (DeviceVendorName, DeviceModelName).
        write_string(&camera, 0x48, 32, "sqscan");
        write_string(&camera, 0x68, 32, "mock line-profile camera");
        camera.write_register(REG_WIDTH, cfg.width);
        camera.write_register(0x11c, cfg.width);
        camera.write_register(REG_HEIGHT, cfg.rows_per_frame);
        camera.write_register(0x118, cfg.rows_per_frame);
        camera.write_register(REG_PIXEL_FORMAT, crate::gige::COORD3D_C16);
        // Areascan until a client asks for profiles, as a camera powers up in its 2D mode.
        camera.write_register(REG_SCAN_TYPE, 0);
        write_f64(&camera, REG_SCALE, cfg.scale);
        write_f64(&camera, REG_OFFSET, cfg.offset);
        camera.write_register(REG_INVALID_FLAG, 1);
        write_f64(&camera, REG_INVALID_VALUE, cfg.invalid_value);
        write_f64(&camera, REG_LINE_RATE, cfg.line_rate_hz);
        // The emulator only asks for frames; `fill` paces them by the line rate.
        camera.write_register(REG_FRAME_PERIOD_US, FRAME_POLL_US);
        let fake_ptr: *mut aravis_sys::ArvFakeCamera = {
            use aravis::glib::translate::ToGlibPtr;
            camera.to_glib_none().0
        };
        let state = Box::into_raw(Box::new(State {
            camera: Mutex::new(camera),
            source: Mutex::new(source),
            clock: cfg.clock,
            epoch: Instant::now(),
            next_row: Mutex::new(None),
        }));
        // SAFETY: the emulator keeps its camera (`fake_ptr`) alive as long as itself; `state`
        // outlives the emulator (see `Drop`), and `fill` matches `ArvFakeCameraFillPattern`.
        unsafe {
            aravis_sys::arv_fake_camera_set_fill_pattern(fake_ptr, Some(fill), state.cast::<c_void>());
        }
        Ok(FakeLineCamera {
            emulator: Some(emulator),
            state,
            fake: fake_ptr,
        })
    }
}

impl Drop for FakeLineCamera {
    fn drop(&mut self) {
        // Taking the callback away waits for a fill under way (the emulator holds its fill
        // mutex while filling); then no fill can reach `state`, whoever still holds the
        // emulator.
        // SAFETY: the emulator (alive until the next line) owns the camera `fake` points to.
        unsafe { aravis_sys::arv_fake_camera_set_fill_pattern(self.fake, None, std::ptr::null_mut()) };
        drop(self.emulator.take());
        // SAFETY: made by `Box::into_raw` in `start`, and nothing uses it any more.
        unsafe { drop(Box::from_raw(self.state)) };
    }
}

/// How often the emulator asks for a frame (us): more often than any block is due.
const FRAME_POLL_US: u32 = 1000;
/// The longest a block may take (s): the fill waits that long at most, on the thread that also
/// answers the control channel.
const MAX_BLOCK_S: f64 = 0.5;

/// When the first row of the next block of `height` rows `period` apart is exposed. The line
/// clock runs on from the last block, whenever the emulator gets round to asking (a busy host
/// asks late: the rows were exposed on time all the same); after a pause (acquisition stopped
/// for a second or more) it starts again now.
fn block_start(state: &State, period: Duration, height: usize) -> Instant {
    let mut next = state.next_row.lock().unwrap_or_else(|p| p.into_inner());
    let now = Instant::now();
    let restart_after = (period * (2 * height as u32)).max(Duration::from_secs(1));
    let first = match *next {
        Some(t) if now.saturating_duration_since(t) < restart_after => t,
        _ => now,
    };
    *next = Some(first + period * height as u32);
    first
}

/// The pixels into the frame's bytes: 16 bits little-endian, or 12 bits packed two in three
/// bytes (`Coord3D_C12p`).
fn pack(pixels: &[u16], bits: usize, bytes: &mut [u8]) {
    if bits == 16 {
        for (dst, p) in bytes.chunks_exact_mut(2).zip(pixels) {
            dst.copy_from_slice(&p.to_le_bytes());
        }
        return;
    }
    for (k, pair) in pixels.chunks(2).enumerate() {
        let a = pair[0];
        let b = pair.get(1).copied().unwrap_or(0);
        let out = [
            a as u8,
            ((a >> 8) & 0x0f) as u8 | ((b & 0x0f) << 4) as u8,
            (b >> 4) as u8,
        ];
        for (j, byte) in out.iter().enumerate() {
            if let Some(d) = bytes.get_mut(3 * k + j) {
                *d = *byte;
            }
        }
    }
}

/// `ArvFakeCameraFillPattern`: called by the emulator's thread for every frame, after it set
/// the frame's size, format, timestamp and id (ours overrides the timestamp).
unsafe extern "C" fn fill(
    buffer: *mut aravis_sys::ArvBuffer,
    data: *mut c_void,
    _exposure_us: u32,
    _gain: u32,
    pixel_format: aravis_sys::ArvPixelFormat,
) {
    // SAFETY: `data` is the `State` given in `start`, alive while the emulator runs.
    let state = unsafe { &*data.cast::<State>() };
    // A panic must not unwind into C; the frame then goes out as it is.
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        // SAFETY: the buffer is the emulator's, valid during the call.
        let (width, height) = unsafe {
            (
                aravis_sys::arv_buffer_get_image_width(buffer).max(0) as usize,
                aravis_sys::arv_buffer_get_image_height(buffer).max(0) as usize,
            )
        };
        let bits = ((pixel_format >> 16) & 0xff) as usize;
        if width == 0 || height == 0 || !(bits == 16 || bits == 12) {
            return;
        }
        // The emulator allocated the frame's payload, width x height x bits / 8 bytes; the size
        // the buffer reports inside this callback is 0.
        let len = width * height * bits / 8;
        let mut ignored = 0usize;
        // SAFETY: as above; the pointer is to `len` writable bytes the emulator owns.
        let bytes = unsafe {
            let p = aravis_sys::arv_buffer_get_data(buffer, &mut ignored);
            if p.is_null() {
                return;
            }
            std::slice::from_raw_parts_mut(p, len)
        };
        let camera = state.camera.lock().unwrap_or_else(|p| p.into_inner());
        let linescan = camera.read_register(REG_SCAN_TYPE) == Some(LINESCAN_3D);
        let scale = read_f64(&camera, REG_SCALE);
        let offset = read_f64(&camera, REG_OFFSET);
        let invalid = read_f64(&camera, REG_INVALID_VALUE);
        let line_rate = read_f64(&camera, REG_LINE_RATE);
        drop(camera);
        // A client may write any rate; one that makes a block take too long (or is no number)
        // is served at the longest block the control channel tolerates.
        let line_rate = if line_rate.is_finite() && line_rate > 0.0 {
            line_rate.max(height as f64 / MAX_BLOCK_S)
        } else {
            height as f64 / MAX_BLOCK_S
        };
        let period = Duration::from_secs_f64(1.0 / line_rate.min(1e6));
        let max = if bits == 16 { 65_535.0 } else { 4_095.0 };
        let first = block_start(state, period, height);
        let last = first + period * (height as u32 - 1);
        let wait = last.saturating_duration_since(Instant::now());
        if !wait.is_zero() {
            std::thread::sleep(wait);
        }
        let mut rows = vec![f64::NAN; width];
        let mut pixels = vec![invalid.clamp(0.0, max) as u16; width * height];
        if linescan {
            let mut source = state.source.lock().unwrap_or_else(|p| p.into_inner());
            for r in 0..height {
                rows.fill(f64::NAN);
                source.row(first + period * r as u32, &mut rows);
                for (c, row) in rows.iter().enumerate() {
                    let v = ((row - offset) / scale).round();
                    if v.is_finite() && v >= 0.0 && v <= max && v != invalid {
                        pixels[r * width + c] = v as u16;
                    }
                }
            }
        }
        pack(&pixels, bits, bytes);
        let host_s = first.saturating_duration_since(state.epoch).as_secs_f64();
        let camera_ns = ((host_s * (1.0 + state.clock.drift_ppm * 1e-6) + state.clock.offset_s) * 1e9).max(0.0);
        // SAFETY: as above.
        unsafe { aravis_sys::arv_buffer_set_timestamp(buffer, camera_ns as u64) };
    }));
}
