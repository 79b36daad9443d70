//! PTU-D46 commands, formatted as ASCII.
//!
//! Conventions we assume (PROTOCOLS.md):
//! - Commands are lower case (the unit is case-insensitive) and each one ends with a single
//!   space. The unit accepts space or CR as the delimiter; a space does not produce an extra
//!   echoed line end, and it is what the public drivers (ros flir_ptu, Player ptu46) send.
//! - Queries are the bare two letters (`pp `); setting appends a signed decimal (`pp-500 `).
//! - Positions are in steps, speeds in steps/s, resolution in arc-seconds per step.
//!
//! ```text
//!  command                 bytes          answer (terse)
//!  terse feedback          "ft "          *
//!  verbose feedback        "fv "          *
//!  echo off / on           "ed " / "ee "  *
//!  independent (position)  "ci "          *
//!  control / velocity      "cv "          *
//!  immediate / slaved      "i " / "s "    *
//!  await completion        "a "           * (when the motion is done)
//!  reset                   "r "           !T!T!P!P*  (up to ~30 s)
//!  halt                    "h "           *          UNVERIFIED syntax, see `PtuCommand::Halt`
//!  position  query / set   "pp " "pp<n> " * <steps> / *      (t.. for tilt)
//!  offset    set           "po<n> "       *
//!  speed     query / set   "ps " "ps<n> " * <steps/s> / *
//!  resolution              "pr "          * <arcsec/step, e.g. 185.1428>
//!  min / max position      "pn " / "px "  * <steps>
//!  upper / lower speed     "pu " / "pl "  * <steps/s>
//!  base speed              "pb "          * <steps/s>
//! ```

use std::fmt;

/// A PTU axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    Pan,
    Tilt,
}

impl Axis {
    const fn letter(self) -> char {
        match self {
            Axis::Pan => 'p',
            Axis::Tilt => 't',
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::Pan => "pan",
            Axis::Tilt => "tilt",
        })
    }
}

/// A per-axis quantity that can be queried (`<axis><letter> `).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AxisQuery {
    /// `pp` / `tp`: absolute position, steps.
    Position,
    /// `ps` / `ts`: target speed, steps/s.
    Speed,
    /// `pr` / `tr`: resolution, arc-seconds per step (a decimal, e.g. 185.1428).
    Resolution,
    /// `pn` / `tn`: minimum position, steps.
    MinPosition,
    /// `px` / `tx`: maximum position, steps.
    MaxPosition,
    /// `pu` / `tu`: upper speed bound, steps/s.
    UpperSpeed,
    /// `pl` / `tl`: lower speed bound, steps/s.
    LowerSpeed,
    /// `pb` / `tb`: base speed, steps/s.
    BaseSpeed,
}

impl AxisQuery {
    const fn letter(self) -> char {
        match self {
            AxisQuery::Position => 'p',
            AxisQuery::Speed => 's',
            AxisQuery::Resolution => 'r',
            AxisQuery::MinPosition => 'n',
            AxisQuery::MaxPosition => 'x',
            AxisQuery::UpperSpeed => 'u',
            AxisQuery::LowerSpeed => 'l',
            AxisQuery::BaseSpeed => 'b',
        }
    }
}

/// One PTU command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PtuCommand {
    /// `ft`: terse feedback (`* 0` instead of sentences).
    FeedbackTerse,
    /// `fv`: verbose feedback.
    FeedbackVerbose,
    /// `ed`: echo off. Drivers send this first; the reply parser copes with echo anyway.
    EchoDisable,
    /// `ee`: echo on (the factory default).
    EchoEnable,
    /// `ci`: independent (position) control mode.
    IndependentControl,
    /// `cv`: velocity control mode.
    VelocityControl,
    /// `i`: immediate execution mode.
    Immediate,
    /// `s`: slaved execution mode (moves wait for `a`).
    Slaved,
    /// `a`: await completion of the current motion.
    Await,
    /// `r`: reset (recalibrate) both axes; answers `!T!T!P!P*` and can take ~30 s.
    Reset,
    /// Halt all motion, sent as `h `. UNVERIFIED: PROTOCOLS.md could not confirm the halt
    /// syntax (the manual family also knows `hp`/`ht` per axis). This is a documented choice; if
    /// a unit wants another form, send it with [`PtuCommand::Raw`].
    Halt,
    /// Query a per-axis quantity, e.g. `pp `.
    Query(Axis, AxisQuery),
    /// `pp<steps> ` / `tp<steps> `: absolute position.
    SetPosition(Axis, i32),
    /// `po<steps> ` / `to<steps> `: relative offset.
    SetOffset(Axis, i32),
    /// `ps<steps/s> ` / `ts<steps/s> `: target speed.
    SetSpeed(Axis, i32),
    /// Any other command text, sent as given plus the delimiting space (configurable syntax
    /// for UNVERIFIED commands such as halt or acceleration). Must be printable ASCII without
    /// spaces; [`PtuCommand::encode`] drops anything else rather than send a broken line.
    Raw(String),
}

impl PtuCommand {
    /// The bytes to write: the command text and one space.
    pub fn encode(&self) -> Vec<u8> {
        self.to_string().into_bytes()
    }

    /// Whether the answer carries a value (`* <value>`) rather than a bare `*`.
    pub fn is_query(&self) -> bool {
        matches!(self, PtuCommand::Query(..))
    }
}

impl fmt::Display for PtuCommand {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PtuCommand::FeedbackTerse => f.write_str("ft "),
            PtuCommand::FeedbackVerbose => f.write_str("fv "),
            PtuCommand::EchoDisable => f.write_str("ed "),
            PtuCommand::EchoEnable => f.write_str("ee "),
            PtuCommand::IndependentControl => f.write_str("ci "),
            PtuCommand::VelocityControl => f.write_str("cv "),
            PtuCommand::Immediate => f.write_str("i "),
            PtuCommand::Slaved => f.write_str("s "),
            PtuCommand::Await => f.write_str("a "),
            PtuCommand::Reset => f.write_str("r "),
            PtuCommand::Halt => f.write_str("h "),
            PtuCommand::Query(axis, q) => write!(f, "{}{} ", axis.letter(), q.letter()),
            PtuCommand::SetPosition(axis, n) => write!(f, "{}p{n} ", axis.letter()),
            PtuCommand::SetOffset(axis, n) => write!(f, "{}o{n} ", axis.letter()),
            PtuCommand::SetSpeed(axis, n) => write!(f, "{}s{n} ", axis.letter()),
            PtuCommand::Raw(text) => {
                for c in text.chars().filter(|c| c.is_ascii_graphic()) {
                    write!(f, "{c}")?;
                }
                f.write_str(" ")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Axis::{Pan, Tilt};

    #[test]
    fn command_bytes() {
        let cases: Vec<(PtuCommand, &str)> = vec![
            (PtuCommand::FeedbackTerse, "ft "),
            (PtuCommand::FeedbackVerbose, "fv "),
            (PtuCommand::EchoDisable, "ed "),
            (PtuCommand::EchoEnable, "ee "),
            (PtuCommand::IndependentControl, "ci "),
            (PtuCommand::VelocityControl, "cv "),
            (PtuCommand::Immediate, "i "),
            (PtuCommand::Slaved, "s "),
            (PtuCommand::Await, "a "),
            (PtuCommand::Reset, "r "),
            (PtuCommand::Halt, "h "),
            (PtuCommand::Query(Pan, AxisQuery::Position), "pp "),
            (PtuCommand::Query(Tilt, AxisQuery::Position), "tp "),
            (PtuCommand::SetPosition(Pan, -500), "pp-500 "),
            (PtuCommand::SetPosition(Tilt, 604), "tp604 "),
            (PtuCommand::SetOffset(Pan, 10), "po10 "),
            (PtuCommand::SetSpeed(Pan, 1000), "ps1000 "),
            (PtuCommand::SetSpeed(Tilt, 800), "ts800 "),
            (PtuCommand::Query(Pan, AxisQuery::Speed), "ps "),
            (PtuCommand::Query(Pan, AxisQuery::Resolution), "pr "),
            (PtuCommand::Query(Tilt, AxisQuery::Resolution), "tr "),
            (PtuCommand::Query(Pan, AxisQuery::MinPosition), "pn "),
            (PtuCommand::Query(Pan, AxisQuery::MaxPosition), "px "),
            (PtuCommand::Query(Tilt, AxisQuery::MinPosition), "tn "),
            (PtuCommand::Query(Tilt, AxisQuery::MaxPosition), "tx "),
            (PtuCommand::Query(Pan, AxisQuery::UpperSpeed), "pu "),
            (PtuCommand::Query(Pan, AxisQuery::LowerSpeed), "pl "),
            (PtuCommand::Query(Pan, AxisQuery::BaseSpeed), "pb "),
            (PtuCommand::Query(Tilt, AxisQuery::BaseSpeed), "tb "),
            (PtuCommand::Raw("hp".into()), "hp "),
            (PtuCommand::Raw("h p\r\n".into()), "hp "),
        ];
        for (cmd, text) in cases {
            assert_eq!(cmd.encode(), text.as_bytes(), "{cmd:?}");
        }
        assert!(PtuCommand::Query(Pan, AxisQuery::Position).is_query());
        assert!(!PtuCommand::SetPosition(Pan, 0).is_query());
    }
}
