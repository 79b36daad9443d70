//! Device codecs for sqscan: bytes, joints and profiles, nothing of superquadrics.
//!
//! Every module here is a pure codec: bytes in, typed frames out, and back. No IO and no async;
//! the device layer that owns serial ports, timeouts and mock devices sits on top. Decoders are
//! incremental (push bytes as they arrive, pop items) and never panic on any input.
//!
//! - [`powercube`]: AMTEC/Schunk PowerCube modules over RS-232 (the pan-tilt unit).
//! - [`flir`]: FLIR / Directed Perception PTU-D46 ASCII protocol.
//! - [`profile`]: our own binary frame for laser profile streams.

#![forbid(unsafe_code)]

pub mod error;
pub mod flir;
pub mod link;
pub mod mock;
pub mod powercube;
pub mod profile;
pub mod ptu;

pub use error::Error;
pub use link::{Link, SerialLink, open_serial};
pub use ptu::{AxisConfig, AxisState, Goal, Limits, PanTilt, PositionSample, PtuState};
