//! Typed PowerCube commands, parameters and replies (the data bytes of a telegram).
//!
//! Over 600 lines on purpose: one command table (the datasheet's, below) with its encoders,
//! reply parsers and byte-literal tests; split by command, the table would no longer read as one.
//!
//! ```text
//!  command      D0    request data                       reply data
//!  RESET        0x00  [00]                               [00]            (echo)
//!  HOME         0x01  [01]                               [01]
//!  HALT         0x02  [02]                               [02]
//!  WATCHDOG     0x07  [07]                               [07]            (echo assumed)
//!  SET_EXT      0x08  [08, param, value LE]              [08, param, ..] (rest UNVERIFIED, ignored)
//!  GET_EXT      0x0A  [0A, param]                        [0A, param, value LE]
//!  SET_MOTION   0x0B  [0B, mode, args LE]                with-reply modes only, see below
//!  STARTMOVE    0x0F  [0F]                               [0F]            (echo assumed)
//!  RESETTIME    0x12  [12]                               [12]            (echo assumed)
//!
//!  motion mode        no reply  with reply  args
//!  FRAMP              0x04      0x0E        f32 target position (rad), ramp with RAMP_VEL/RAMP_ACC
//!  FSTEP              0x06      0x10        f32 target position (rad), u16 time (ms)
//!  FVEL               0x07      0x11        f32 velocity (rad/s)
//!  with-reply reply:  [0B, mode, f32 actual position (rad), u8 short state, u8 dio]
//!
//!  param        code  type   unit
//!  VERSION      0x1D  u16    firmware version
//!  CUBESTATE    0x27  u32    flags, see CubeState
//!  ACT_POS      0x3C  f32    rad
//!  ACT_VEL      0x41  f32    rad/s
//!  MIN_POS      0x45  f32    rad
//!  MAX_POS      0x46  f32    rad
//!  MAX_VEL      0x48  f32    rad/s
//!  MAX_ACC      0x4A  f32    rad/s^2
//!  RAMP_VEL     0x4F  f32    rad/s   (write)
//!  RAMP_ACC     0x50  f32    rad/s^2 (write)
//! ```
//! All multi-byte values are little-endian.

use super::frame::{Direction, Frame, ModuleId, Payload};
use super::state::ShortState;

/// Command bytes (D0).
pub mod code {
    pub const RESET: u8 = 0x00;
    pub const HOME: u8 = 0x01;
    pub const HALT: u8 = 0x02;
    pub const WATCHDOG: u8 = 0x07;
    pub const SET_EXT: u8 = 0x08;
    pub const GET_EXT: u8 = 0x0A;
    pub const SET_MOTION: u8 = 0x0B;
    pub const STARTMOVE: u8 = 0x0F;
    pub const RESETTIME: u8 = 0x12;
}

/// Motion mode bytes (D1 of SET_MOTION).
pub mod mode {
    pub const FRAMP: u8 = 0x04;
    pub const FSTEP: u8 = 0x06;
    pub const FVEL: u8 = 0x07;
    /// Added to a mode for its with-reply variant.
    pub const WITH_REPLY: u8 = 0x0A;
    pub const FRAMP_ACK: u8 = FRAMP + WITH_REPLY;
    pub const FSTEP_ACK: u8 = FSTEP + WITH_REPLY;
    pub const FVEL_ACK: u8 = FVEL + WITH_REPLY;
}

/// What is wrong with the data bytes of a telegram (the framing was fine).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    #[error("telegram has no data bytes")]
    Empty,
    #[error("unknown command byte {0:#04x}")]
    UnknownCommand(u8),
    #[error("unknown parameter {0:#04x}")]
    UnknownParam(u8),
    #[error("unknown motion mode {0:#04x}")]
    UnknownMotionMode(u8),
    #[error("command {command:#04x}: {len} data bytes is not a valid length")]
    BadLength { command: u8, len: usize },
    #[error("telegram is not the reply to this request")]
    NotTheReply,
}

/// A module parameter, for SET_EXT / GET_EXT.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Param {
    Version = 0x1D,
    CubeState = 0x27,
    ActPos = 0x3C,
    ActVel = 0x41,
    MinPos = 0x45,
    MaxPos = 0x46,
    MaxVel = 0x48,
    MaxAcc = 0x4A,
    RampVel = 0x4F,
    RampAcc = 0x50,
}

impl Param {
    pub const ALL: [Param; 10] = [
        Param::Version,
        Param::CubeState,
        Param::ActPos,
        Param::ActVel,
        Param::MinPos,
        Param::MaxPos,
        Param::MaxVel,
        Param::MaxAcc,
        Param::RampVel,
        Param::RampAcc,
    ];

    pub const fn code(self) -> u8 {
        self as u8
    }

    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.code() == code)
    }

    /// The wire type of the parameter's value.
    pub const fn kind(self) -> ValueKind {
        match self {
            Param::Version => ValueKind::U16,
            Param::CubeState => ValueKind::U32,
            _ => ValueKind::F32,
        }
    }
}

/// Wire type of a parameter value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ValueKind {
    F32,
    U32,
    U16,
}

impl ValueKind {
    /// Bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            ValueKind::F32 | ValueKind::U32 => 4,
            ValueKind::U16 => 2,
        }
    }
}

/// A parameter value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    F32(f32),
    U32(u32),
    U16(u16),
}

impl Value {
    pub const fn kind(self) -> ValueKind {
        match self {
            Value::F32(_) => ValueKind::F32,
            Value::U32(_) => ValueKind::U32,
            Value::U16(_) => ValueKind::U16,
        }
    }

    pub const fn as_f32(self) -> Option<f32> {
        match self {
            Value::F32(v) => Some(v),
            _ => None,
        }
    }

    pub const fn as_u32(self) -> Option<u32> {
        match self {
            Value::U32(v) => Some(v),
            _ => None,
        }
    }

    pub const fn as_u16(self) -> Option<u16> {
        match self {
            Value::U16(v) => Some(v),
            _ => None,
        }
    }

    /// Reads a value of `kind` from exactly `bytes` (little-endian); `None` on a size mismatch.
    pub fn read(kind: ValueKind, bytes: &[u8]) -> Option<Self> {
        Some(match kind {
            ValueKind::F32 => Value::F32(f32::from_le_bytes(bytes.try_into().ok()?)),
            ValueKind::U32 => Value::U32(u32::from_le_bytes(bytes.try_into().ok()?)),
            ValueKind::U16 => Value::U16(u16::from_le_bytes(bytes.try_into().ok()?)),
        })
    }

    fn write(self, p: &mut Payload) -> bool {
        match self {
            Value::F32(v) => p.extend(&v.to_le_bytes()),
            Value::U32(v) => p.extend(&v.to_le_bytes()),
            Value::U16(v) => p.extend(&v.to_le_bytes()),
        }
    }
}

/// Where a SET_MOTION command sends the joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionTarget {
    /// FRAMP: trapezoidal ramp to a position, with the RAMP_VEL / RAMP_ACC parameters.
    Ramp { pos_rad: f32 },
    /// FSTEP: reach a position in a given time.
    Step { pos_rad: f32, time_ms: u16 },
    /// FVEL: run at a velocity.
    Velocity { vel_rad_s: f32 },
}

/// A SET_MOTION command: a target and whether the module should answer it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub target: MotionTarget,
    /// Use the with-reply mode (base + 0x0A): the module answers with position and short state.
    pub with_reply: bool,
}

impl Motion {
    /// The mode byte.
    pub const fn mode(&self) -> u8 {
        let base = match self.target {
            MotionTarget::Ramp { .. } => mode::FRAMP,
            MotionTarget::Step { .. } => mode::FSTEP,
            MotionTarget::Velocity { .. } => mode::FVEL,
        };
        if self.with_reply { base + mode::WITH_REPLY } else { base }
    }
}

/// A command to one module (the telegram's data bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    Reset,
    Home,
    Halt,
    /// WATCHDOG 0x07, sent as the bare command byte (no argument documented).
    Watchdog,
    SetExt {
        param: Param,
        value: Value,
    },
    GetExt(Param),
    SetMotion(Motion),
    StartMove,
    ResetTime,
}

impl Command {
    /// The command byte D0.
    pub const fn code(&self) -> u8 {
        match self {
            Command::Reset => code::RESET,
            Command::Home => code::HOME,
            Command::Halt => code::HALT,
            Command::Watchdog => code::WATCHDOG,
            Command::SetExt { .. } => code::SET_EXT,
            Command::GetExt(_) => code::GET_EXT,
            Command::SetMotion(_) => code::SET_MOTION,
            Command::StartMove => code::STARTMOVE,
            Command::ResetTime => code::RESETTIME,
        }
    }

    /// The data bytes. Every command fits the 8 bytes of a telegram (FSTEP, the longest, is 8).
    pub fn payload(&self) -> Payload {
        let mut p = Payload::default();
        p.push(self.code());
        match *self {
            Command::SetExt { param, value } => {
                p.push(param.code());
                value.write(&mut p);
            }
            Command::GetExt(param) => {
                p.push(param.code());
            }
            Command::SetMotion(m) => {
                p.push(m.mode());
                match m.target {
                    MotionTarget::Ramp { pos_rad } => p.extend(&pos_rad.to_le_bytes()),
                    MotionTarget::Step { pos_rad, time_ms } => {
                        p.extend(&pos_rad.to_le_bytes()) && p.extend(&time_ms.to_le_bytes())
                    }
                    MotionTarget::Velocity { vel_rad_s } => p.extend(&vel_rad_s.to_le_bytes()),
                };
            }
            _ => {}
        }
        p
    }

    /// Whether the module answers. Only the no-reply motion modes stay silent: that is what
    /// distinguishes them from their with-reply variants.
    pub const fn expects_reply(&self) -> bool {
        match self {
            Command::SetMotion(m) => m.with_reply,
            _ => true,
        }
    }

    /// Parses request data bytes (the mock module's side).
    pub fn parse(data: &[u8]) -> Result<Self, CommandError> {
        let (&c, args) = data.split_first().ok_or(CommandError::Empty)?;
        let bad_len = CommandError::BadLength {
            command: c,
            len: data.len(),
        };
        let no_args = |cmd: Command| {
            if args.is_empty() { Ok(cmd) } else { Err(bad_len) }
        };
        match c {
            code::RESET => no_args(Command::Reset),
            code::HOME => no_args(Command::Home),
            code::HALT => no_args(Command::Halt),
            code::WATCHDOG => no_args(Command::Watchdog),
            code::STARTMOVE => no_args(Command::StartMove),
            code::RESETTIME => no_args(Command::ResetTime),
            code::GET_EXT => match args {
                [p] => Ok(Command::GetExt(param(*p)?)),
                _ => Err(bad_len),
            },
            code::SET_EXT => {
                let (&p, raw) = args.split_first().ok_or(bad_len)?;
                let param = param(p)?;
                let value = Value::read(param.kind(), raw).ok_or(bad_len)?;
                Ok(Command::SetExt { param, value })
            }
            code::SET_MOTION => {
                let (&m, raw) = args.split_first().ok_or(bad_len)?;
                let with_reply = matches!(m, mode::FRAMP_ACK | mode::FSTEP_ACK | mode::FVEL_ACK);
                let base = if with_reply { m - mode::WITH_REPLY } else { m };
                let target = match (base, raw) {
                    (mode::FRAMP, &[a, b, c, d]) => MotionTarget::Ramp {
                        pos_rad: f32::from_le_bytes([a, b, c, d]),
                    },
                    (mode::FSTEP, &[a, b, c, d, t0, t1]) => MotionTarget::Step {
                        pos_rad: f32::from_le_bytes([a, b, c, d]),
                        time_ms: u16::from_le_bytes([t0, t1]),
                    },
                    (mode::FVEL, &[a, b, c, d]) => MotionTarget::Velocity {
                        vel_rad_s: f32::from_le_bytes([a, b, c, d]),
                    },
                    (mode::FRAMP | mode::FSTEP | mode::FVEL, _) => return Err(bad_len),
                    _ => return Err(CommandError::UnknownMotionMode(m)),
                };
                Ok(Command::SetMotion(Motion { target, with_reply }))
            }
            other => Err(CommandError::UnknownCommand(other)),
        }
    }

    /// Whether reply data bytes answer this command: the command byte is echoed, and so is the
    /// parameter (SET_EXT, GET_EXT) or the mode (SET_MOTION).
    pub fn is_answered_by(&self, data: &[u8]) -> bool {
        match (self, data) {
            (Command::SetExt { param, .. } | Command::GetExt(param), [c, p, ..]) => {
                *c == self.code() && *p == param.code()
            }
            (Command::SetMotion(m), [c, md, ..]) => *c == code::SET_MOTION && *md == m.mode(),
            (Command::SetExt { .. } | Command::GetExt(_) | Command::SetMotion(_), _) => false,
            (_, [c, ..]) => *c == self.code(),
            (_, []) => false,
        }
    }
}

fn param(code: u8) -> Result<Param, CommandError> {
    Param::from_code(code).ok_or(CommandError::UnknownParam(code))
}

/// A module's answer (the reply telegram's data bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reply {
    /// Echo of a command without arguments: RESET, HOME, HALT, WATCHDOG, STARTMOVE, RESETTIME.
    /// Bytes after the echo, if a firmware sends any, are ignored.
    Ack { command: u8 },
    /// SET_EXT acknowledged. What follows `[08, param]` is UNVERIFIED and ignored.
    SetExt { param: Param },
    /// GET_EXT answered.
    GetExt { param: Param, value: Value },
    /// Echo `[0B, mode]` of a motion command without position data (a no-reply mode that
    /// answered anyway; tolerated).
    Motion { mode: u8 },
    /// Answer to a with-reply motion mode.
    MotionAck {
        mode: u8,
        pos_rad: f32,
        state: ShortState,
        dio: u8,
    },
}

impl Reply {
    /// Parses reply data bytes. Replies are self-describing (command byte and parameter echoed).
    pub fn parse(data: &[u8]) -> Result<Self, CommandError> {
        let (&c, args) = data.split_first().ok_or(CommandError::Empty)?;
        let bad_len = CommandError::BadLength {
            command: c,
            len: data.len(),
        };
        match c {
            code::RESET | code::HOME | code::HALT | code::WATCHDOG | code::STARTMOVE | code::RESETTIME => {
                Ok(Reply::Ack { command: c })
            }
            code::SET_EXT => {
                let &p = args.first().ok_or(bad_len)?;
                Ok(Reply::SetExt { param: param(p)? })
            }
            code::GET_EXT => {
                let (&p, raw) = args.split_first().ok_or(bad_len)?;
                let param = param(p)?;
                let value = Value::read(param.kind(), raw).ok_or(bad_len)?;
                Ok(Reply::GetExt { param, value })
            }
            code::SET_MOTION => match *args {
                [m] => Ok(Reply::Motion { mode: m }),
                [m, a, b, c, d, state, dio] => Ok(Reply::MotionAck {
                    mode: m,
                    pos_rad: f32::from_le_bytes([a, b, c, d]),
                    state: ShortState(state),
                    dio,
                }),
                _ => Err(bad_len),
            },
            other => Err(CommandError::UnknownCommand(other)),
        }
    }

    /// The data bytes a module sends (the mock module's side). For SET_EXT we send the bare
    /// `[08, param]` echo, the one part of that reply PROTOCOLS.md confirms.
    pub fn payload(&self) -> Payload {
        let mut p = Payload::default();
        match *self {
            Reply::Ack { command } => {
                p.push(command);
            }
            Reply::SetExt { param } => {
                p.extend(&[code::SET_EXT, param.code()]);
            }
            Reply::GetExt { param, value } => {
                p.extend(&[code::GET_EXT, param.code()]);
                value.write(&mut p);
            }
            Reply::Motion { mode } => {
                p.extend(&[code::SET_MOTION, mode]);
            }
            Reply::MotionAck {
                mode,
                pos_rad,
                state,
                dio,
            } => {
                p.extend(&[code::SET_MOTION, mode]);
                p.extend(&pos_rad.to_le_bytes());
                p.extend(&[state.0, dio]);
            }
        }
        p
    }
}

/// A command addressed to a module: what the driver sends and then waits for an answer to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub module: ModuleId,
    pub command: Command,
}

impl Request {
    pub const fn new(module: ModuleId, command: Command) -> Self {
        Self { module, command }
    }

    pub fn frame(&self) -> Frame {
        Frame::request(self.module, self.command.payload())
    }

    /// The bytes to write to the serial line.
    pub fn encode(&self) -> Vec<u8> {
        self.frame().encode()
    }

    /// Is `frame` the reply to this request: from the module (not an echo of a request on a
    /// shared line), same module id, command byte and parameter/mode echoed.
    pub fn is_reply(&self, frame: &Frame) -> bool {
        frame.direction == Direction::ToHost
            && frame.module == self.module
            && self.command.is_answered_by(frame.data.as_slice())
    }

    /// Parses `frame` as the reply to this request.
    pub fn parse_reply(&self, frame: &Frame) -> Result<Reply, CommandError> {
        if !self.is_reply(frame) {
            return Err(CommandError::NotTheReply);
        }
        Reply::parse(frame.data.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::powercube::frame::FrameDecoder;

    fn id(n: u8) -> ModuleId {
        ModuleId::new(n).expect("valid test module id")
    }

    fn all_commands() -> Vec<Command> {
        let mut v = vec![
            Command::Reset,
            Command::Home,
            Command::Halt,
            Command::Watchdog,
            Command::StartMove,
            Command::ResetTime,
        ];
        for p in Param::ALL {
            v.push(Command::GetExt(p));
            let value = match p.kind() {
                ValueKind::F32 => Value::F32(-1.25),
                ValueKind::U32 => Value::U32(0x0403_0210),
                ValueKind::U16 => Value::U16(0x1002),
            };
            v.push(Command::SetExt { param: p, value });
        }
        for with_reply in [false, true] {
            for target in [
                MotionTarget::Ramp { pos_rad: 0.5 },
                MotionTarget::Step {
                    pos_rad: -0.25,
                    time_ms: 1000,
                },
                MotionTarget::Velocity { vel_rad_s: 0.1 },
            ] {
                v.push(Command::SetMotion(Motion { target, with_reply }));
            }
        }
        v
    }

    #[test]
    fn every_command_round_trips_through_the_wire() {
        for module in [1, 8, 12, 16, 24, 31] {
            for cmd in all_commands() {
                let req = Request::new(id(module), cmd);
                let mut d = FrameDecoder::new();
                d.push(&req.encode());
                let frame = d.next_frame().expect("a frame").expect("valid");
                assert_eq!(frame, req.frame());
                assert_eq!(Command::parse(frame.data.as_slice()), Ok(cmd), "{cmd:?}");
                assert_eq!(d.next_frame(), None);
            }
        }
    }

    #[test]
    fn command_byte_literals() {
        assert_eq!(Command::GetExt(Param::ActPos).payload().as_slice(), [0x0A, 0x3C]);
        assert_eq!(
            Command::SetExt {
                param: Param::RampVel,
                value: Value::F32(0.5)
            }
            .payload()
            .as_slice(),
            [0x08, 0x4F, 0x00, 0x00, 0x00, 0x3F]
        );
        let fstep = Motion {
            target: MotionTarget::Step {
                pos_rad: 1.0,
                time_ms: 0x0102,
            },
            with_reply: true,
        };
        assert_eq!(
            Command::SetMotion(fstep).payload().as_slice(),
            [0x0B, 0x10, 0x00, 0x00, 0x80, 0x3F, 0x02, 0x01]
        );
        let fvel = Motion {
            target: MotionTarget::Velocity { vel_rad_s: -2.0 },
            with_reply: false,
        };
        assert_eq!(
            Command::SetMotion(fvel).payload().as_slice(),
            [0x0B, 0x07, 0, 0, 0, 0xC0]
        );
        let framp = Motion {
            target: MotionTarget::Ramp { pos_rad: 0.0 },
            with_reply: true,
        };
        assert_eq!(Command::SetMotion(framp).payload().as_slice(), [0x0B, 0x0E, 0, 0, 0, 0]);
        assert_eq!(Command::Reset.payload().as_slice(), [0x00]);
        assert_eq!(Command::Home.payload().as_slice(), [0x01]);
        assert_eq!(Command::Halt.payload().as_slice(), [0x02]);
        assert_eq!(Command::Watchdog.payload().as_slice(), [0x07]);
        assert_eq!(Command::StartMove.payload().as_slice(), [0x0F]);
        assert_eq!(Command::ResetTime.payload().as_slice(), [0x12]);
    }

    #[test]
    fn act_pos_reply_from_the_worked_example() {
        let mut d = FrameDecoder::new();
        d.push(&[0x02, 0x09, 0x86, 0x0A, 0x3C, 0x00, 0x00, 0x00, 0x3F, 0x15, 0x03]);
        let frame = d.next_frame().unwrap().unwrap();
        let req = Request::new(id(12), Command::GetExt(Param::ActPos));
        assert!(req.is_reply(&frame));
        assert_eq!(
            req.parse_reply(&frame),
            Ok(Reply::GetExt {
                param: Param::ActPos,
                value: Value::F32(0.5)
            })
        );
        // Not the reply for another module, another parameter, or a request frame.
        assert!(!Request::new(id(11), Command::GetExt(Param::ActPos)).is_reply(&frame));
        assert!(!Request::new(id(12), Command::GetExt(Param::ActVel)).is_reply(&frame));
        assert!(!Request::new(id(12), Command::Reset).is_reply(&frame));
        assert!(!req.is_reply(&req.frame()));
        assert_eq!(
            Request::new(id(11), Command::GetExt(Param::ActPos)).parse_reply(&frame),
            Err(CommandError::NotTheReply)
        );
    }

    #[test]
    fn every_reply_round_trips_and_matches_its_request() {
        let replies = |cmd: &Command| -> Option<Reply> {
            Some(match *cmd {
                Command::GetExt(param) => Reply::GetExt {
                    param,
                    value: match param.kind() {
                        ValueKind::F32 => Value::F32(0.75),
                        ValueKind::U32 => Value::U32(0x8802),
                        ValueKind::U16 => Value::U16(0x3512),
                    },
                },
                Command::SetExt { param, .. } => Reply::SetExt { param },
                Command::SetMotion(m) if m.with_reply => Reply::MotionAck {
                    mode: m.mode(),
                    pos_rad: 0.125,
                    state: ShortState(0x30),
                    dio: 0x03,
                },
                Command::SetMotion(_) => return None,
                other => Reply::Ack { command: other.code() },
            })
        };
        for cmd in all_commands() {
            let req = Request::new(id(8), cmd);
            assert_eq!(replies(&cmd).is_some(), cmd.expects_reply());
            let Some(reply) = replies(&cmd) else { continue };
            let wire = Frame::reply(id(8), reply.payload()).encode();
            let mut d = FrameDecoder::new();
            d.push(&wire);
            let frame = d.next_frame().unwrap().unwrap();
            assert_eq!(req.parse_reply(&frame), Ok(reply), "{cmd:?}");
        }
    }

    #[test]
    fn set_ext_reply_tolerates_trailing_bytes() {
        // UNVERIFIED payload after the echo: accept the echo plus anything.
        assert_eq!(
            Reply::parse(&[0x08, 0x4F, 0x00, 0x00]),
            Ok(Reply::SetExt { param: Param::RampVel })
        );
    }

    #[test]
    fn malformed_data_gives_typed_errors() {
        assert_eq!(Command::parse(&[]), Err(CommandError::Empty));
        assert_eq!(Command::parse(&[0x55]), Err(CommandError::UnknownCommand(0x55)));
        assert_eq!(Command::parse(&[0x0A, 0x99]), Err(CommandError::UnknownParam(0x99)));
        assert_eq!(
            Command::parse(&[0x0A, 0x3C, 0x00]),
            Err(CommandError::BadLength { command: 0x0A, len: 3 })
        );
        assert_eq!(
            Command::parse(&[0x0B, 0x05, 0, 0, 0, 0]),
            Err(CommandError::UnknownMotionMode(0x05))
        );
        assert_eq!(
            Command::parse(&[0x0B, 0x06, 0, 0, 0, 0]),
            Err(CommandError::BadLength { command: 0x0B, len: 6 })
        );
        assert_eq!(
            Reply::parse(&[0x0A, 0x27, 0x01]),
            Err(CommandError::BadLength { command: 0x0A, len: 3 })
        );
        assert_eq!(
            Reply::parse(&[0x0B, 0x10, 0, 0]),
            Err(CommandError::BadLength { command: 0x0B, len: 4 })
        );
    }

    #[test]
    fn cubestate_reply() {
        let reply = Reply::parse(&[0x0A, 0x27, 0x03, 0x88, 0x00, 0x00]).unwrap();
        let Reply::GetExt { value, .. } = reply else {
            panic!("{reply:?}")
        };
        let state = crate::powercube::CubeState(value.as_u32().unwrap());
        assert_eq!(state.to_string(), "ERROR|HOME_OK|MOTION|RAMP_END");
    }
}
