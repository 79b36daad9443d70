//! The crate's error type.
//!
//! Codecs have their own small error enums (they describe one telegram or line and carry no
//! allocation-heavy context); the device layer wraps them into [`Error`] so callers can tell a
//! timeout from a checksum fault from an unplugged device and retry accordingly.

use std::time::Duration;

use crate::flir::PtuError;
use crate::powercube::{CommandError, CubeState, FrameError, ModuleId};
use crate::profile::ProfileError;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// No (matching) answer in time.
    #[error("timed out after {after:?} waiting for {waiting_for}")]
    Timeout { waiting_for: &'static str, after: Duration },

    /// A PowerCube telegram was malformed or failed its checksum.
    #[error("PowerCube framing: {0}")]
    PowerCubeFrame(#[from] FrameError),

    /// A PowerCube telegram was well framed but its data made no sense.
    #[error("PowerCube data: {0}")]
    PowerCubeData(#[from] CommandError),

    /// A profile frame was malformed or failed its CRC.
    #[error("profile frame: {0}")]
    ProfileFrame(#[from] ProfileError),

    /// The FLIR PTU refused a command (`! ...`) or hit a limit (`!P` / `!T`).
    #[error("PTU: {0}")]
    Ptu(#[from] PtuError),

    /// A PowerCube module reports a fault in its CUBESTATE; it needs a RESET.
    #[error("{module} fault: {state}")]
    DeviceFault { module: ModuleId, state: CubeState },

    /// A GigE Vision camera could not be opened, set up or driven (the message names its
    /// address).
    #[error("GigE Vision camera {0}")]
    Camera(String),

    /// A GenICam feature could not be set or read, or holds what cannot be used.
    #[error("camera feature {feature}: {message}")]
    Feature { feature: String, message: String },

    /// The device went away (port closed, pty master dropped, EOF).
    #[error("device disconnected")]
    Disconnected,

    /// The port could not be opened (missing, busy, no permission).
    #[error("cannot open {}: {source}", path.display())]
    Open {
        path: std::path::PathBuf,
        source: std::io::Error,
    },

    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),

    /// Well-formed, but not what the exchange called for (e.g. a value where `*` was expected).
    #[error("unexpected reply: expected {expected}, got {got}")]
    Protocol { expected: &'static str, got: String },

    /// A requested value the device or the codec cannot represent.
    #[error("{quantity} = {value} outside [{min}, {max}]")]
    OutOfRange {
        quantity: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
}

impl Error {
    /// A corrupted or lost message rather than a device or configuration problem: retrying the
    /// same exchange may succeed.
    pub fn is_transient(&self) -> bool {
        matches!(
            self,
            Error::Timeout { .. } | Error::PowerCubeFrame(_) | Error::ProfileFrame(_)
        )
    }

    /// A checksum or CRC mismatch (line noise), as opposed to malformed framing.
    pub fn is_checksum(&self) -> bool {
        match self {
            Error::PowerCubeFrame(e) => e.is_checksum(),
            Error::ProfileFrame(e) => matches!(e, ProfileError::BadCrc { .. }),
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codec_errors_convert_and_classify() {
        let e: Error = FrameError::BadChecksum {
            received: 1,
            schunk: 2,
            player: 3,
        }
        .into();
        assert!(e.is_checksum() && e.is_transient());
        let e: Error = FrameError::BadEscape(0x41).into();
        assert!(!e.is_checksum() && e.is_transient());
        let e = Error::DeviceFault {
            module: ModuleId::new(12).expect("valid id"),
            state: CubeState(0x9),
        };
        assert_eq!(e.to_string(), "module 12 fault: ERROR|POWERFAULT");
        assert!(!e.is_transient());
        let e: Error = std::io::Error::from(std::io::ErrorKind::BrokenPipe).into();
        assert!(matches!(e, Error::Io(_)));
    }
}
