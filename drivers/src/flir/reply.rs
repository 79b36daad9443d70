//! Incremental parser for what a PTU-D46 sends back.
//!
//! A received line is read as `[echo] marker...`, where a marker is one of
//!
//! ```text
//!  "*"                    ok                              -> PtuReply::Ok
//!  "* <number>"           query answer (terse)            -> PtuReply::Value
//!  "* <sentence>"         verbose answer; the first number in it is the value, e.g.
//!                         "* Current Pan position is 0"  -> PtuReply::Value(0)
//!                         no number at all               -> PtuReply::Info(text)
//!  "!P" / "!T"            asynchronous pan / tilt limit hit (several may share a line:
//!                         the reset answer is "!T!T!P!P*") -> PtuReply::LimitHit
//!  "! <message>"          error                           -> PtuReply::Error(PtuError)
//! ```
//!
//! Anything before the first `*` or `!` is the unit echoing our command (echo is on by default;
//! drivers send `ed ` but must survive the replies before it takes effect) and is dropped.
//! A line with no marker at all (a lone echo, a power-up banner, noise) becomes
//! [`PtuReply::Unparsed`]. Lines end with CR LF (inferred from the public drivers); CR alone or
//! LF alone also end a line, and empty lines are skipped, so any mix works. Over-long lines are
//! cut at [`MAX_LINE_LEN`] bytes and reported as unparsed.
//!
//! Resynchronisation is per line: whatever came before, a line end followed by a valid reply
//! line yields exactly that reply.

use std::collections::VecDeque;

use super::command::Axis;

/// Longest line kept; longer input is cut into unparsed pieces (PTU lines are < 100 bytes).
pub const MAX_LINE_LEN: usize = 256;

/// A number in a `*` answer: steps and speeds are integers, resolution is a decimal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Number {
    Int(i64),
    Float(f64),
}

impl Number {
    /// The integer, if the unit sent one (positions, limits, speeds).
    pub fn as_i64(self) -> Option<i64> {
        match self {
            Number::Int(v) => Some(v),
            Number::Float(_) => None,
        }
    }

    /// The value as a float (either form).
    pub fn as_f64(self) -> f64 {
        match self {
            Number::Int(v) => v as f64,
            Number::Float(v) => v,
        }
    }
}

/// An error the PTU reported.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PtuError {
    /// A value beyond a limit, e.g. `! Maximum allowable Pan position is 3090` after `pp3200`.
    #[error("out of range: {0}")]
    OutOfRange(String),
    /// `! Illegal Command` and the like.
    #[error("illegal command: {0}")]
    IllegalCommand(String),
    /// `! Illegal Command Argument` and the like.
    #[error("illegal argument: {0}")]
    IllegalArgument(String),
    /// `!P` / `!T`: the axis ran into its limit.
    #[error("{0} limit hit")]
    LimitHit(Axis),
    /// Any other `! <message>`, with the raw text.
    #[error("{0}")]
    Other(String),
}

impl PtuError {
    /// Classifies the text after `!` (case-insensitively, by the words the manual uses).
    pub fn from_message(message: &str) -> Self {
        let text = message.trim().to_string();
        let lower = text.to_ascii_lowercase();
        if lower.contains("illegal") && lower.contains("argument") {
            PtuError::IllegalArgument(text)
        } else if lower.contains("illegal") || lower.contains("unknown") {
            PtuError::IllegalCommand(text)
        } else if ["range", "allowable", "exceed", "limit"]
            .iter()
            .any(|w| lower.contains(w))
        {
            PtuError::OutOfRange(text)
        } else {
            PtuError::Other(text)
        }
    }
}

/// One item of PTU output.
#[derive(Clone, Debug, PartialEq)]
pub enum PtuReply {
    /// `*`: command accepted.
    Ok,
    /// `* <value>` or a verbose sentence containing a value.
    Value(Number),
    /// `* <text>` with no number in it (a verbose acknowledgement).
    Info(String),
    /// `! <message>`.
    Error(PtuError),
    /// `!P` / `!T`, asynchronous or part of the reset answer.
    LimitHit(Axis),
    /// A line that is none of the above (echo-only line, banner, noise), lossily decoded.
    Unparsed(String),
}

/// Incremental reply parser: push bytes as they arrive, pop replies.
///
/// Bytes are split into lines as they are pushed; only complete lines produce replies.
#[derive(Debug, Default)]
pub struct ReplyParser {
    line: Vec<u8>,
    out: VecDeque<PtuReply>,
}

impl ReplyParser {
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            match b {
                b'\r' | b'\n' => self.end_line(),
                _ => {
                    self.line.push(b);
                    if self.line.len() >= MAX_LINE_LEN {
                        let text = String::from_utf8_lossy(&self.line).into_owned();
                        self.line.clear();
                        self.out.push_back(PtuReply::Unparsed(text));
                    }
                }
            }
        }
    }

    /// The next reply from the complete lines received so far.
    pub fn next_reply(&mut self) -> Option<PtuReply> {
        self.out.pop_front()
    }

    /// Treats the bytes after the last line end as a complete line, for a caller whose line has
    /// gone quiet without a line end (e.g. a unit that does not terminate the reset answer).
    pub fn flush_line(&mut self) {
        self.end_line();
    }

    /// Bytes of the current, unterminated line.
    pub fn partial_len(&self) -> usize {
        self.line.len()
    }

    /// Drops the partial line and undelivered replies.
    pub fn reset(&mut self) {
        self.line.clear();
        self.out.clear();
    }

    fn end_line(&mut self) {
        if self.line.is_empty() {
            return;
        }
        let text = String::from_utf8_lossy(&self.line).into_owned();
        self.line.clear();
        parse_line(&text, &mut self.out);
    }
}

/// Parses one line (without its line end) into replies.
pub fn parse_line(line: &str, out: &mut VecDeque<PtuReply>) {
    let Some(marker) = line.find(['*', '!']) else {
        if !line.trim().is_empty() {
            out.push_back(PtuReply::Unparsed(line.to_string()));
        }
        return;
    };
    // `find` returned a char boundary, so this slice cannot fail; `get` keeps it panic-free.
    let mut rest = line.get(marker..).unwrap_or("");
    loop {
        rest = rest.trim_start();
        if let Some(after) = rest.strip_prefix('!') {
            if let Some((axis, tail)) = limit_hit(after) {
                out.push_back(PtuReply::LimitHit(axis));
                rest = tail;
                continue;
            }
            out.push_back(PtuReply::Error(PtuError::from_message(after)));
        } else if let Some(after) = rest.strip_prefix('*') {
            let text = after.trim();
            out.push_back(if text.is_empty() {
                PtuReply::Ok
            } else if let Some(n) = first_number(text) {
                PtuReply::Value(n)
            } else {
                PtuReply::Info(text.to_string())
            });
        } else if !rest.is_empty() {
            out.push_back(PtuReply::Unparsed(rest.to_string()));
        }
        return;
    }
}

/// `P`/`T` right after `!`, standing alone (end, space, or the next marker): a limit hit.
fn limit_hit(after_bang: &str) -> Option<(Axis, &str)> {
    let mut chars = after_bang.chars();
    let axis = match chars.next()? {
        'P' | 'p' => Axis::Pan,
        'T' | 't' => Axis::Tilt,
        _ => return None,
    };
    let tail = chars.as_str();
    match tail.chars().next() {
        None | Some('!' | '*') => Some((axis, tail)),
        Some(c) if c.is_whitespace() => Some((axis, tail)),
        Some(_) => None,
    }
}

/// The first whitespace-separated token that is a number, ignoring sentence punctuation.
fn first_number(text: &str) -> Option<Number> {
    text.split_whitespace().find_map(|token| {
        let t = token
            .trim_end_matches([',', ';', ':', '.', ')'])
            .trim_start_matches('(');
        let numeric = t.bytes().any(|b| b.is_ascii_digit())
            && t.bytes().all(|b| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.'));
        if !numeric {
            return None;
        }
        t.parse::<i64>()
            .map(Number::Int)
            .ok()
            .or_else(|| t.parse::<f64>().ok().filter(|v| v.is_finite()).map(Number::Float))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(bytes: &[u8]) -> Vec<PtuReply> {
        let mut p = ReplyParser::new();
        p.push(bytes);
        std::iter::from_fn(|| p.next_reply()).collect()
    }

    use PtuReply::*;

    #[test]
    fn terse_transcript_without_echo() {
        let got = parse(b"*\r\n* 0\r\n* -500\r\n* 185.1428\r\n*\r\n");
        assert_eq!(
            got,
            [
                Ok,
                Value(Number::Int(0)),
                Value(Number::Int(-500)),
                Value(Number::Float(185.1428)),
                Ok
            ]
        );
    }

    #[test]
    fn start_up_with_echo_on() {
        // The unit echoes each command until `ed ` takes effect; the echo of `ed ` itself comes
        // back before its `*`.
        let got = parse(b"ft *\r\ned *\r\nci *\r\n*\r\npp * 0\r\n");
        assert_eq!(got, [Ok, Ok, Ok, Ok, Value(Number::Int(0))]);
    }

    #[test]
    fn echoed_set_command_and_error() {
        let got = parse(b"pp3200 ! Maximum allowable Pan position is 3090\r\n");
        assert_eq!(
            got,
            [Error(PtuError::OutOfRange(
                "Maximum allowable Pan position is 3090".into()
            ))]
        );
    }

    #[test]
    fn verbose_sentences() {
        let got = parse(
            b"* Current Pan position is 0\r\n\
              * Pan resolution is 185.1428 seconds arc per position\r\n\
              * Maximum Pan position is 3090.\r\n\
              * Minimum Tilt position is -907\r\n\
              * Executing\r\n",
        );
        assert_eq!(
            got,
            [
                Value(Number::Int(0)),
                Value(Number::Float(185.1428)),
                Value(Number::Int(3090)),
                Value(Number::Int(-907)),
                Info("Executing".into()),
            ]
        );
    }

    #[test]
    fn errors_are_typed() {
        let got = parse(
            b"! Illegal Command\r\n! Illegal Command Argument\r\n! Pan speed out of range\r\n! something else\r\n",
        );
        assert_eq!(
            got,
            [
                Error(PtuError::IllegalCommand("Illegal Command".into())),
                Error(PtuError::IllegalArgument("Illegal Command Argument".into())),
                Error(PtuError::OutOfRange("Pan speed out of range".into())),
                Error(PtuError::Other("something else".into())),
            ]
        );
    }

    #[test]
    fn reset_answer_and_async_limit_hits() {
        assert_eq!(
            parse(b" r !T!T!P!P*\r\n"),
            [
                LimitHit(Axis::Tilt),
                LimitHit(Axis::Tilt),
                LimitHit(Axis::Pan),
                LimitHit(Axis::Pan),
                Ok
            ]
        );
        assert_eq!(parse(b"!P\r\n* 12\r\n"), [LimitHit(Axis::Pan), Value(Number::Int(12))]);
        assert_eq!(parse(b"!T* 12\r\n"), [LimitHit(Axis::Tilt), Value(Number::Int(12))]);
    }

    #[test]
    fn line_ends_cr_lf_crlf_and_partial_lines() {
        assert_eq!(
            parse(b"*\r* 1\n* 2\r\n\r\n* 3"),
            [Ok, Value(Number::Int(1)), Value(Number::Int(2))]
        );
        let mut p = ReplyParser::new();
        p.push(b"* 4");
        assert_eq!(p.next_reply(), None);
        p.push(b"2\r");
        assert_eq!(p.next_reply(), Some(Value(Number::Int(42))));
        p.push(b"!T!T!P!P*");
        assert_eq!(p.next_reply(), None);
        p.flush_line();
        let got: Vec<_> = std::iter::from_fn(|| p.next_reply()).collect();
        assert_eq!(got.len(), 5);
        assert_eq!(got.last(), Some(&Ok));
    }

    #[test]
    fn garbage_is_unparsed_never_a_panic() {
        let got = parse(b"Pan-Tilt Controller v2.13.4r0(D46-17)\r\n\xFF\xFE\x00\r\npp\r\n*** \r\n");
        assert_eq!(got[0], Unparsed("Pan-Tilt Controller v2.13.4r0(D46-17)".into()));
        assert!(matches!(&got[1], Unparsed(_)));
        assert_eq!(got[2], Unparsed("pp".into()));
        // "*** ": an ok whose text "**" has no number.
        assert_eq!(got[3], Info("**".into()));
        let long = vec![b'x'; MAX_LINE_LEN * 2 + 10];
        let got = parse(&[&long[..], b"\r\n* 7\r\n"].concat());
        assert_eq!(got.len(), 4);
        assert_eq!(got[3], Value(Number::Int(7)));
    }

    #[test]
    fn whole_session_byte_by_byte() {
        // Power-up banner, start-up with echo still on, resolution and limit queries, a move,
        // a refused move, an asynchronous limit hit, and a reset answer.
        let transcript: &[u8] = b"Pan-Tilt Controller v2.13.4r0(D46-17/E)\r\n\
            ft *\r\ned *\r\n*\r\n*\r\n\
            * 185.1428\r\n* 46.2857\r\n* -3090\r\n* 3090\r\n\
            *\r\n! Maximum allowable Pan position is 3090\r\n!P\r\n\
            !T!T!P!P*\r\n";
        let mut p = ReplyParser::new();
        let mut got = Vec::new();
        for b in transcript {
            p.push(std::slice::from_ref(b));
            got.extend(std::iter::from_fn(|| p.next_reply()));
        }
        assert_eq!(
            got,
            [
                Unparsed("Pan-Tilt Controller v2.13.4r0(D46-17/E)".into()),
                Ok,
                Ok,
                Ok,
                Ok,
                Value(Number::Float(185.1428)),
                Value(Number::Float(46.2857)),
                Value(Number::Int(-3090)),
                Value(Number::Int(3090)),
                Ok,
                Error(PtuError::OutOfRange("Maximum allowable Pan position is 3090".into())),
                LimitHit(Axis::Pan),
                LimitHit(Axis::Tilt),
                LimitHit(Axis::Tilt),
                LimitHit(Axis::Pan),
                LimitHit(Axis::Pan),
                Ok,
            ]
        );
        assert_eq!(p.partial_len(), 0);
    }

    #[test]
    fn numbers() {
        assert_eq!(first_number("is 3090."), Some(Number::Int(3090)));
        assert_eq!(first_number("v2 D46-17 (12)"), Some(Number::Int(12)));
        assert_eq!(first_number("inf nan 1e5"), None);
        assert_eq!(first_number("+-"), None);
        assert_eq!(Number::Int(3).as_f64(), 3.0);
        assert_eq!(Number::Float(0.5).as_i64(), None);
    }
}
