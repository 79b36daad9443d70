//! Device drivers for sqscan: bytes, joints and profiles, nothing of superquadrics.
//!
//! Two layers. The codecs are pure: bytes in, typed frames out, and back, no IO and no async;
//! decoders are incremental (push bytes as they arrive, pop items) and never panic on any input.
//! On top, the async device layer owns links, timeouts, retries and mock devices.
//!
//! - [`powercube`]: AMTEC/Schunk PowerCube modules over RS-232 (the pan-tilt unit): codec and
//!   the async [`powercube::PowerCubePtu`].
//! - [`flir`]: FLIR / Directed Perception PTU-D46 ASCII protocol: codec and the async
//!   [`flir::FlirPtu`].
//! - [`profile`]: our own binary frame for laser profile streams (codec).
//! - [`gige`]: GigE Vision line-profile cameras: their blocks of profiles (pure), and with the
//!   `gige` feature the camera through aravis.
//! - [`ptu`]: the [`PanTilt`] trait every PTU driver implements.
//! - [`kind`]: the table of PTU kinds ([`PtuKind`]): names, default line speeds, how to open
//!   each driver ([`AnyPtu`]) and which mock device stands in for it.
//! - [`sensor`]: the profile sensor device ([`sensor::ProfileSensor`]) and its START/STOP lines.
//! - [`link`]: opening serial ports; telling an unplugged device from other IO errors.
//! - [`mock`]: mock devices written from the device's side, served on pseudo-terminals.

// The only unsafe code is the aravis glue of the `gige` feature (raw frame buffers and the
// camera emulator's fill callback), each use allowed where it is.
#![deny(unsafe_code)]

pub mod error;
pub mod flir;
pub mod gige;
pub mod kind;
pub mod link;
pub mod mock;
pub mod powercube;
pub mod profile;
pub mod ptu;
pub mod sensor;

pub use error::Error;
pub use kind::{AnyPtu, PtuKind, PtuSettings};
pub use link::{Link, SerialLink, open_serial};
pub use ptu::{AxisConfig, AxisState, Goal, Limits, PanTilt, PositionSample, PtuState};
