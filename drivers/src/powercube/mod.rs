//! AMTEC/Schunk PowerCube modules over RS-232.
//!
//! - [`frame`]: telegram framing (STX/ETX, escaping, TelID, BCC) and the incremental [`FrameDecoder`].
//! - [`command`]: typed commands, parameters and replies, and the reply matcher.
//! - [`state`]: the CUBESTATE and short-state flag words.

pub mod command;
pub mod device;
pub mod frame;
pub mod state;

pub use command::{Command, CommandError, Motion, MotionTarget, Param, Reply, Request, Value, ValueKind};
pub use device::{Joint, LinkStats, PowerCubeConfig, PowerCubePtu};
pub use frame::{
    ChecksumForm, DecoderStats, Direction, Frame, FrameDecoder, FrameError, ModuleId, Payload, encode_reply,
    encode_request, player_bcc, schunk_bcc,
};
pub use state::{CubeState, ShortState};
