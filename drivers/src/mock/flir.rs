//! A mock FLIR / Directed Perception PTU-D46, written from the unit's side.
//!
//! Its command reader is its own (it does not use the driver's [`PtuCommand`] formatting), so it
//! checks the driver rather than mirroring it. Behaviour:
//!
//! * Commands are case-insensitive tokens ended by a space, CR or LF.
//! * Power-up state is the factory one: echo on (every token is echoed before its answer, on
//!   the same line), verbose answers (`* Current Pan position is 0`) until `ft `, echo off after
//!   `ed `.
//! * Each axis moves at its set speed (steps/s) toward its target, without acceleration (the
//!   unit's acceleration commands are UNVERIFIED, see PROTOCOLS.md); positions are whole steps.
//! * A position or speed beyond the axis' bounds is refused with a `!` sentence
//!   (`! Maximum allowable Pan position is 3090`) and nothing moves. Unknown commands answer
//!   `! Illegal Command`.
//! * `i ` executes moves at once; `s ` (slaved) stores them until `a `. `a ` answers `*` once
//!   both axes stand still; `r ` drives both axes to 0 at their upper speed and then answers
//!   `!T!T!P!P*` like the real recalibration. While one of them is pending the unit reads no
//!   further commands (they wait in its input buffer), as the real unit blocks.
//! * `h ` halts both axes where they are.
//!
//! [`PtuCommand`]: crate::flir::PtuCommand

use std::time::Instant;

use super::MockDevice;

/// Longest command token kept; longer ones are refused as illegal.
const MAX_TOKEN: usize = 32;

/// One simulated axis' fixed properties.
#[derive(Clone, Debug, PartialEq)]
pub struct MockFlirAxisConfig {
    /// `pr`/`tr`: arc-seconds per step.
    pub resolution_arcsec: f64,
    pub min_steps: i64,
    pub max_steps: i64,
    /// `pu`/`tu`: upper speed bound, steps/s.
    pub upper_speed: i64,
    /// `pl`/`tl`: lower speed bound, steps/s.
    pub lower_speed: i64,
    /// Speed at power-up, steps/s.
    pub initial_speed: i64,
    /// Position at power-up, steps.
    pub initial_steps: i64,
}

/// The mock unit's configuration: a PTU-D46-17 as in the manual's examples, 185.1428 arcsec
/// (0.0514 deg) a step on both axes, pan limits ±3090 steps (±159 deg), tilt -907..604 steps
/// (-47..+31 deg).
#[derive(Clone, Debug, PartialEq)]
pub struct MockFlirConfig {
    pub pan: MockFlirAxisConfig,
    pub tilt: MockFlirAxisConfig,
}

impl Default for MockFlirConfig {
    fn default() -> Self {
        Self {
            pan: MockFlirAxisConfig {
                resolution_arcsec: 185.1428,
                min_steps: -3090,
                max_steps: 3090,
                upper_speed: 2902,
                lower_speed: 1,
                initial_speed: 1000,
                initial_steps: 0,
            },
            tilt: MockFlirAxisConfig {
                resolution_arcsec: 185.1428,
                min_steps: -907,
                max_steps: 604,
                upper_speed: 2902,
                lower_speed: 1,
                initial_speed: 1000,
                initial_steps: 0,
            },
        }
    }
}

#[derive(Clone, Debug)]
struct MockAxis {
    cfg: MockFlirAxisConfig,
    name: &'static str,
    /// Continuous position (steps); reported rounded.
    pos: f64,
    target: f64,
    speed: f64,
    /// A target set in slaved mode, waiting for `a `.
    pending_target: Option<f64>,
    at: Option<Instant>,
}

impl MockAxis {
    fn new(cfg: MockFlirAxisConfig, name: &'static str) -> Self {
        Self {
            name,
            pos: cfg.initial_steps as f64,
            target: cfg.initial_steps as f64,
            speed: cfg.initial_speed as f64,
            pending_target: None,
            at: None,
            cfg,
        }
    }

    fn advance(&mut self, now: Instant) {
        let dt = self
            .at
            .map_or(0.0, |at| now.saturating_duration_since(at).as_secs_f64());
        self.at = Some(self.at.map_or(now, |at| at.max(now)));
        let d = self.target - self.pos;
        let step = self.speed * dt;
        self.pos = if d.abs() <= step {
            self.target
        } else {
            self.pos + d.signum() * step
        };
    }

    fn steps(&self) -> i64 {
        self.pos.round() as i64
    }

    fn moving(&self) -> bool {
        self.pos != self.target
    }

    fn rad(&self) -> f64 {
        self.pos * self.cfg.resolution_arcsec / (180.0 * 3600.0) * std::f64::consts::PI
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Blocked {
    Await,
    Reset,
}

/// The mock unit.
#[derive(Debug)]
pub struct MockFlirPtu {
    pan: MockAxis,
    tilt: MockAxis,
    echo: bool,
    terse: bool,
    immediate: bool,
    token: Vec<u8>,
    /// Input not yet read because an `a ` or `r ` is pending.
    backlog: Vec<u8>,
    blocked: Option<Blocked>,
    /// Commands refused (illegal or out of range), for tests.
    pub refused: u64,
}

impl MockFlirPtu {
    pub fn new(cfg: MockFlirConfig) -> Self {
        Self {
            pan: MockAxis::new(cfg.pan, "Pan"),
            tilt: MockAxis::new(cfg.tilt, "Tilt"),
            echo: true,
            terse: false,
            immediate: true,
            token: Vec::new(),
            backlog: Vec::new(),
            blocked: None,
            refused: 0,
        }
    }

    /// Position of both axes in steps at `now`.
    pub fn steps(&mut self, now: Instant) -> (i64, i64) {
        self.advance(now);
        (self.pan.steps(), self.tilt.steps())
    }

    pub fn echo(&self) -> bool {
        self.echo
    }

    pub fn terse(&self) -> bool {
        self.terse
    }

    fn advance(&mut self, now: Instant) {
        self.pan.advance(now);
        self.tilt.advance(now);
    }

    /// Reads bytes as the unit's input buffer does, executing complete tokens.
    fn read(&mut self, bytes: &[u8], now: Instant, out: &mut Vec<Vec<u8>>) {
        for (i, &b) in bytes.iter().enumerate() {
            if self.blocked.is_some() {
                self.backlog.extend_from_slice(bytes.get(i..).unwrap_or_default());
                return;
            }
            if matches!(b, b' ' | b'\r' | b'\n') {
                if !self.token.is_empty() {
                    let token = std::mem::take(&mut self.token);
                    out.extend(self.execute(&token, now));
                }
            } else if self.token.len() < MAX_TOKEN {
                self.token.push(b.to_ascii_lowercase());
            } else {
                // Too long to be a command: it will be refused as illegal when it ends.
                self.token.truncate(MAX_TOKEN);
            }
        }
    }

    fn line(&self, token: &[u8], answer: &str) -> Vec<u8> {
        let mut line = Vec::new();
        if self.echo {
            line.extend_from_slice(token);
            line.push(b' ');
        }
        line.extend_from_slice(answer.as_bytes());
        line.extend_from_slice(b"\r\n");
        line
    }

    fn refuse(&mut self, token: &[u8], message: &str) -> Option<Vec<u8>> {
        self.refused += 1;
        Some(self.line(token, &format!("! {message}")))
    }

    /// One command; `None` when the answer is deferred (`a `, `r `).
    fn execute(&mut self, token: &[u8], now: Instant) -> Option<Vec<u8>> {
        self.advance(now);
        let ok = |s: &Self| Some(s.line(token, "*"));
        match token {
            b"ft" => {
                self.terse = true;
                ok(self)
            }
            b"fv" => {
                self.terse = false;
                ok(self)
            }
            b"ed" => {
                // The echo of `ed ` itself is already on the line.
                let line = self.line(token, "*");
                self.echo = false;
                Some(line)
            }
            b"ee" => {
                self.echo = true;
                ok(self)
            }
            b"ci" | b"cv" => ok(self),
            b"i" => {
                self.immediate = true;
                ok(self)
            }
            b"s" => {
                self.immediate = false;
                ok(self)
            }
            b"h" => {
                for axis in [&mut self.pan, &mut self.tilt] {
                    axis.target = axis.pos;
                    axis.pending_target = None;
                }
                ok(self)
            }
            b"a" => {
                for axis in [&mut self.pan, &mut self.tilt] {
                    if let Some(t) = axis.pending_target.take() {
                        axis.target = t;
                    }
                }
                self.blocked = Some(Blocked::Await);
                None
            }
            b"r" => {
                for axis in [&mut self.pan, &mut self.tilt] {
                    axis.target = 0.0;
                    axis.pending_target = None;
                    axis.speed = axis.cfg.upper_speed as f64;
                }
                self.blocked = Some(Blocked::Reset);
                None
            }
            _ => self.axis_command(token),
        }
    }

    /// `<axis><letter>[<signed integer>]`.
    fn axis_command(&mut self, token: &[u8]) -> Option<Vec<u8>> {
        let (Some(&a), Some(&q)) = (token.first(), token.get(1)) else {
            return self.refuse(token, "Illegal Command");
        };
        let arg = token.get(2..).unwrap_or_default();
        let value = if arg.is_empty() {
            None
        } else {
            match std::str::from_utf8(arg).ok().and_then(|s| s.parse::<i64>().ok()) {
                Some(v) => Some(v),
                None => return self.refuse(token, "Illegal Command Argument"),
            }
        };
        let terse = self.terse;
        let immediate = self.immediate;
        let axis = match a {
            b'p' => &mut self.pan,
            b't' => &mut self.tilt,
            _ => return self.refuse(token, "Illegal Command"),
        };
        let name = axis.name;
        let answer = |what: &str, v: String| {
            if terse {
                format!("* {v}")
            } else {
                format!("* {what} {name} {v}")
            }
        };
        let result: Result<String, String> = match (q, value) {
            (b'p', None) => Ok(answer("Current position of", axis.steps().to_string())),
            (b's', None) => Ok(answer("Target speed of", (axis.speed as i64).to_string())),
            (b'r', None) => Ok(if terse {
                format!("* {}", axis.cfg.resolution_arcsec)
            } else {
                format!(
                    "* {name} resolution is {} seconds arc per position",
                    axis.cfg.resolution_arcsec
                )
            }),
            (b'n', None) => Ok(answer("Minimum position of", axis.cfg.min_steps.to_string())),
            (b'x', None) => Ok(answer("Maximum position of", axis.cfg.max_steps.to_string())),
            (b'u', None) => Ok(answer("Upper speed bound of", axis.cfg.upper_speed.to_string())),
            (b'l', None) => Ok(answer("Lower speed bound of", axis.cfg.lower_speed.to_string())),
            (b'p' | b'o', Some(v)) => {
                let target = if q == b'o' {
                    (axis.target.round() as i64).saturating_add(v)
                } else {
                    v
                };
                if target > axis.cfg.max_steps {
                    Err(format!("Maximum allowable {name} position is {}", axis.cfg.max_steps))
                } else if target < axis.cfg.min_steps {
                    Err(format!("Minimum allowable {name} position is {}", axis.cfg.min_steps))
                } else {
                    if immediate {
                        axis.target = target as f64;
                    } else {
                        axis.pending_target = Some(target as f64);
                    }
                    Ok("*".into())
                }
            }
            (b's', Some(v)) => {
                if v > axis.cfg.upper_speed {
                    Err(format!("Maximum allowable {name} speed is {}", axis.cfg.upper_speed))
                } else if v < axis.cfg.lower_speed {
                    Err(format!("Minimum allowable {name} speed is {}", axis.cfg.lower_speed))
                } else {
                    axis.speed = v as f64;
                    Ok("*".into())
                }
            }
            _ => Err("Illegal Command".into()),
        };
        match result {
            Ok(answer) => Some(self.line(token, &answer)),
            Err(message) => self.refuse(token, &message),
        }
    }
}

impl MockDevice for MockFlirPtu {
    fn receive(&mut self, bytes: &[u8], now: Instant) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        self.read(bytes, now, &mut out);
        out
    }

    /// No checksum to break: the reply loses its `*`/`!` marker, so it reads as noise (as a
    /// reply mangled on the line does) and the driver times out and retries.
    fn corrupt(&self, reply: &[u8]) -> Vec<u8> {
        reply
            .iter()
            .map(|&b| if matches!(b, b'*' | b'!') { b'?' } else { b })
            .collect()
    }

    /// Line noise a line protocol without a checksum can survive: no markers, ended by a line
    /// end (random bytes that happen to spell `* 5` would be indistinguishable from a reply).
    fn noise(&self, junk: Vec<u8>) -> Vec<u8> {
        let mut out: Vec<u8> = junk
            .into_iter()
            .map(|b| {
                if matches!(b, b'*' | b'!' | b'\r' | b'\n') {
                    b'#'
                } else {
                    b
                }
            })
            .collect();
        out.extend_from_slice(b"\r\n");
        out
    }

    fn joint_angles(&mut self, now: Instant) -> (f64, f64) {
        self.advance(now);
        (self.pan.rad(), self.tilt.rad())
    }

    fn wants_poll(&self) -> bool {
        self.blocked.is_some()
    }

    fn poll(&mut self, now: Instant) -> Vec<Vec<u8>> {
        self.advance(now);
        let Some(blocked) = self.blocked else {
            return Vec::new();
        };
        if self.pan.moving() || self.tilt.moving() {
            return Vec::new();
        }
        self.blocked = None;
        let mut out = vec![match blocked {
            Blocked::Await => self.line(b"a", "*"),
            Blocked::Reset => self.line(b"r", "!T!T!P!P*"),
        }];
        let backlog = std::mem::take(&mut self.backlog);
        self.read(&backlog, now, &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn text(out: Vec<Vec<u8>>) -> String {
        out.into_iter()
            .map(|l| String::from_utf8_lossy(&l).into_owned())
            .collect()
    }

    #[test]
    fn start_up_turns_echo_and_sentences_off() {
        let mut m = MockFlirPtu::new(MockFlirConfig::default());
        let t = Instant::now();
        assert_eq!(
            text(m.receive(b"pp PR ", t)),
            "pp * Current position of Pan 0\r\npr * Pan resolution is 185.1428 seconds arc per position\r\n"
        );
        assert_eq!(text(m.receive(b"ft ed ", t)), "ft *\r\ned *\r\n");
        assert_eq!(text(m.receive(b"tp\rtx\n", t)), "* 0\r\n* 604\r\n");
    }

    #[test]
    fn moves_at_the_set_speed_and_refuses_out_of_range() {
        let mut m = MockFlirPtu::new(MockFlirConfig::default());
        let t0 = Instant::now();
        m.receive(b"ft ed ps500 pp1000 ", t0);
        assert_eq!(m.steps(t0 + Duration::from_millis(1000)), (500, 0));
        assert_eq!(m.steps(t0 + Duration::from_millis(3000)), (1000, 0));
        assert_eq!(
            text(m.receive(b"pp3200 ts9999 tp-5 TP-907 xx ", t0)),
            "! Maximum allowable Pan position is 3090\r\n\
             ! Maximum allowable Tilt speed is 2902\r\n*\r\n*\r\n! Illegal Command\r\n"
        );
        assert_eq!(m.refused, 3);
    }

    #[test]
    fn await_and_reset_answer_when_motion_ends_and_block_input() {
        let mut m = MockFlirPtu::new(MockFlirConfig::default());
        let t0 = Instant::now();
        m.receive(b"ft ed ps1000 pp100 ", t0);
        assert!(m.receive(b"a pp ", t0).is_empty());
        assert!(m.wants_poll());
        assert!(m.poll(t0 + Duration::from_millis(50)).is_empty());
        // The `pp ` waited in the input buffer until `a ` was answered.
        assert_eq!(text(m.poll(t0 + Duration::from_millis(200))), "*\r\n* 100\r\n");
        assert!(m.receive(b"r ", t0 + Duration::from_millis(200)).is_empty());
        assert_eq!(text(m.poll(t0 + Duration::from_secs(2))), "!T!T!P!P*\r\n");
        assert_eq!(m.steps(t0 + Duration::from_secs(2)), (0, 0));
    }

    #[test]
    fn corrupted_replies_and_noise_have_no_markers() {
        let m = MockFlirPtu::new(MockFlirConfig::default());
        assert_eq!(m.corrupt(b"* 5\r\n"), b"? 5\r\n");
        assert_eq!(m.noise(b"a*\n!b".to_vec()), b"a###b\r\n");
    }
}
