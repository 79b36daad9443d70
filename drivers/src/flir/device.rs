//! The async FLIR / Directed Perception PTU-D46 over any byte stream.
//!
//! The ASCII protocol has no request ids and no checksum, so a reply is matched to its command by
//! order and by shape: a query wants `* <value>`, anything else wants `*` (or a verbose
//! sentence). A `! <message>` answer is the unit refusing the command and becomes
//! [`Error::Ptu`] at once (not retried: the unit would refuse again). Noise lines (no marker, or
//! a marker-less fragment of a corrupted reply) are counted and skipped; a reply of the wrong
//! shape (a `*` where a value was due) is counted as stray and skipped. A reply that does not
//! come within the timeout is retried a bounded number of times: every command we send is
//! idempotent (absolute positions and speeds, queries, mode switches), so resending is safe.
//!
//! Because there are no ids, a reply later than the timeout could be taken for the answer to the
//! next command of the same shape. The driver drains whatever has arrived before it sends a
//! command, so this needs a reply to arrive between the drain and the next answer: keep the
//! reply timeout well above the unit's worst answer time (the default is ~30 reply lengths at
//! 9600 baud).

use std::path::Path;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::mpsc::UnboundedSender;
use tokio::time::{MissedTickBehavior, timeout, timeout_at};

use super::{Axis, AxisQuery, Number, PtuCommand, PtuError, PtuReply, ReplyParser, Resolution};
use crate::Error;
use crate::link::{Link, SerialLink, classify_io, deadline_after, open_serial};
use crate::ptu::{AxisConfig, AxisState, Goal, Limits, PanTilt, PositionSample, PtuState};

/// Configuration of a PTU-D46. Defaults: 9600 baud (the factory setting), no axis remapping.
#[derive(Clone, Debug, PartialEq)]
pub struct FlirConfig {
    pub baud: u32,
    pub pan: AxisConfig,
    pub tilt: AxisConfig,
    /// How long to wait for one reply. A reply line is ~10 bytes, ~10 ms at 9600 baud; the rest
    /// is slack for the unit and a loaded host.
    pub reply_timeout: Duration,
    /// Extra attempts after a lost reply.
    pub retries: u32,
    /// Position sampling period while tracking a move (50 ms = 20 Hz: `pp` and `tp` with their
    /// answers take ~25 ms of the line at 9600 baud).
    pub sample_period: Duration,
    /// The reset (`r `) must be answered within this; the manual allows ~30 s.
    pub home_timeout: Duration,
}

impl Default for FlirConfig {
    fn default() -> Self {
        Self {
            baud: 9600,
            pan: AxisConfig::default(),
            tilt: AxisConfig::default(),
            reply_timeout: Duration::from_millis(300),
            retries: 2,
            sample_period: Duration::from_millis(50),
            home_timeout: Duration::from_secs(60),
        }
    }
}

/// What the link has been through (for status output and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FlirStats {
    pub exchanges: u64,
    /// Commands sent again after a lost reply.
    pub retries: u64,
    /// Replies that did not arrive in time.
    pub timeouts: u64,
    /// Lines that were not replies (banner, noise, a corrupted reply).
    pub noise_lines: u64,
    /// Replies of the wrong shape for the command (e.g. a late `*`).
    pub stray_replies: u64,
    /// `!P` / `!T` seen (four belong to every reset answer).
    pub limit_hits: u64,
}

/// What the unit reported about one axis at start-up, in steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlirAxisInfo {
    pub resolution: Resolution,
    pub min_steps: i32,
    pub max_steps: i32,
    /// Upper speed bound (`pu`/`tu`), steps/s.
    pub max_speed_steps: i32,
}

/// A PTU-D46 over any byte stream.
pub struct FlirPtu<S> {
    link: S,
    cfg: FlirConfig,
    parser: ReplyParser,
    pan: FlirAxisInfo,
    tilt: FlirAxisInfo,
    limits: Limits,
    /// The goal of the current move, in steps (pan, tilt) and steps/s of the slower axis.
    goal: Option<GoalSteps>,
    /// An asynchronous `!P`/`!T` since the last move started.
    limit_hit: Option<Axis>,
    stats: FlirStats,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct GoalSteps {
    pan: i64,
    tilt: i64,
    /// The slower of the two axis speeds (steps/s): how long "no change" may last while moving.
    min_speed: i64,
}

impl FlirPtu<SerialLink> {
    /// Opens the serial port at `path` and starts the unit (see [`FlirPtu::new`]).
    pub async fn open(path: &Path, cfg: FlirConfig) -> Result<Self, Error> {
        let link = open_serial(path, cfg.baud)?;
        Self::new(link, cfg).await
    }

    /// Reopens the port by the same path (after an unplug) and starts the unit again.
    pub async fn reconnect(&mut self) -> Result<(), Error> {
        let path = self.link.path().to_owned();
        self.link = open_serial(&path, self.cfg.baud)?;
        self.parser.reset();
        self.start().await
    }
}

impl<S: Link> FlirPtu<S> {
    /// Starts the unit on `link` as the public drivers do (`ft `, `ed `, `ci `, `i `: terse
    /// answers, echo off, position control, immediate execution), then reads both axes'
    /// resolution, position limits and upper speed bound. Does not reset: that moves the unit
    /// through its whole range (see [`PanTilt::home`]).
    pub async fn new(link: S, cfg: FlirConfig) -> Result<Self, Error> {
        let placeholder = FlirAxisInfo {
            resolution: Resolution::from_arcsec_per_step(1.0).unwrap_or_else(|| unreachable!("1 arcsec/step is valid")),
            min_steps: 0,
            max_steps: 0,
            max_speed_steps: 0,
        };
        let mut ptu = Self {
            link,
            cfg,
            parser: ReplyParser::new(),
            pan: placeholder,
            tilt: placeholder,
            limits: Limits {
                pan_rad: (0.0, 0.0),
                tilt_rad: (0.0, 0.0),
            },
            goal: None,
            limit_hit: None,
            stats: FlirStats::default(),
        };
        ptu.start().await?;
        Ok(ptu)
    }

    async fn start(&mut self) -> Result<(), Error> {
        for cmd in [
            PtuCommand::FeedbackTerse,
            PtuCommand::EchoDisable,
            PtuCommand::IndependentControl,
            PtuCommand::Immediate,
        ] {
            self.command(&cmd).await?;
        }
        self.pan = self.axis_info(Axis::Pan).await?;
        self.tilt = self.axis_info(Axis::Tilt).await?;
        let interval = |info: &FlirAxisInfo, axis: &AxisConfig| {
            axis.interval_to_joint((
                info.resolution.steps_to_rad(i64::from(info.min_steps)),
                info.resolution.steps_to_rad(i64::from(info.max_steps)),
            ))
        };
        self.limits = Limits {
            pan_rad: interval(&self.pan, &self.cfg.pan),
            tilt_rad: interval(&self.tilt, &self.cfg.tilt),
        };
        self.goal = None;
        Ok(())
    }

    async fn axis_info(&mut self, axis: Axis) -> Result<FlirAxisInfo, Error> {
        let arcsec = self.query(axis, AxisQuery::Resolution).await?.as_f64();
        let resolution = Resolution::from_arcsec_per_step(arcsec).ok_or(Error::Protocol {
            expected: "a positive resolution (arcsec/step)",
            got: arcsec.to_string(),
        })?;
        let min_steps = self.query_steps(axis, AxisQuery::MinPosition).await?;
        let max_steps = self.query_steps(axis, AxisQuery::MaxPosition).await?;
        let max_speed_steps = self.query_steps(axis, AxisQuery::UpperSpeed).await?;
        if min_steps >= max_steps || max_speed_steps <= 0 {
            return Err(Error::Protocol {
                expected: "min < max position and a positive upper speed",
                got: format!("{axis}: [{min_steps}, {max_steps}], speed {max_speed_steps}"),
            });
        }
        Ok(FlirAxisInfo {
            resolution,
            min_steps,
            max_steps,
            max_speed_steps,
        })
    }

    pub fn config(&self) -> &FlirConfig {
        &self.cfg
    }

    pub fn stats(&self) -> FlirStats {
        self.stats
    }

    /// What the unit reported about an axis at start-up.
    pub fn axis(&self, axis: Axis) -> FlirAxisInfo {
        match axis {
            Axis::Pan => self.pan,
            Axis::Tilt => self.tilt,
        }
    }

    /// The link, e.g. to close it.
    pub fn into_inner(self) -> S {
        self.link
    }

    fn mapping(&self, axis: Axis) -> AxisConfig {
        match axis {
            Axis::Pan => self.cfg.pan,
            Axis::Tilt => self.cfg.tilt,
        }
    }

    /// Sends one command and waits for its answer, with the reply timeout and retries: the
    /// value of a query, `None` for any other command.
    pub async fn command(&mut self, cmd: &PtuCommand) -> Result<Option<Number>, Error> {
        self.exchange(cmd, self.cfg.reply_timeout).await
    }

    /// A query's value as a step count (positions, limits, speeds are integers).
    pub async fn query_steps(&mut self, axis: Axis, q: AxisQuery) -> Result<i32, Error> {
        let n = self.query(axis, q).await?;
        n.as_i64().and_then(|v| i32::try_from(v).ok()).ok_or(Error::Protocol {
            expected: "an integer step count",
            got: format!("{n:?}"),
        })
    }

    async fn query(&mut self, axis: Axis, q: AxisQuery) -> Result<Number, Error> {
        let cmd = PtuCommand::Query(axis, q);
        self.command(&cmd).await?.ok_or(Error::Protocol {
            expected: "a value",
            got: "an acknowledgement".into(),
        })
    }

    /// `a `: waits (up to `wait`) until the unit reports the current motion complete.
    pub async fn await_completion(&mut self, wait: Duration) -> Result<(), Error> {
        self.exchange(&PtuCommand::Await, wait).await?;
        self.goal = None;
        Ok(())
    }

    /// `r `: recalibrates both axes (the unit runs into its end stops, answering `!T!T!P!P*`)
    /// and waits for the answer, up to the home timeout.
    pub async fn reset(&mut self) -> Result<(), Error> {
        self.goal = None;
        self.exchange(&PtuCommand::Reset, self.cfg.home_timeout).await?;
        // The reset answer's limit hits are the recalibration, not a fault.
        self.limit_hit = None;
        Ok(())
    }

    async fn exchange(&mut self, cmd: &PtuCommand, wait: Duration) -> Result<Option<Number>, Error> {
        let wire = cmd.encode();
        let want_value = cmd.is_query();
        self.stats.exchanges += 1;
        let mut last = None;
        for attempt in 0..=self.cfg.retries {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            self.drain_stale().await?;
            self.link.write_all(&wire).await.map_err(classify_io)?;
            self.link.flush().await.map_err(classify_io)?;
            match self.await_reply(want_value, wait).await {
                Ok(v) => return Ok(v),
                Err(e) if e.is_transient() => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or(Error::Timeout {
            waiting_for: "PTU reply",
            after: wait,
        }))
    }

    /// Reads what has already arrived and drops it (a late answer to an earlier attempt), so it
    /// cannot be taken for the answer to the command about to be sent. Limit hits in it are
    /// still noted.
    async fn drain_stale(&mut self) -> Result<(), Error> {
        let mut buf = [0u8; 256];
        // A zero timeout polls the read once: it returns what is buffered, never waits.
        while let Ok(r) = timeout(Duration::ZERO, self.link.read(&mut buf)).await {
            match r {
                Ok(0) => return Err(Error::Disconnected),
                Ok(n) => self.parser.push(buf.get(..n).unwrap_or_default()),
                Err(e) => return Err(classify_io(e)),
            }
        }
        self.parser.flush_line();
        while let Some(reply) = self.parser.next_reply() {
            self.note_unsolicited(reply);
        }
        Ok(())
    }

    fn note_unsolicited(&mut self, reply: PtuReply) {
        match reply {
            PtuReply::LimitHit(axis) => {
                self.stats.limit_hits += 1;
                self.limit_hit = Some(axis);
            }
            PtuReply::Unparsed(_) => self.stats.noise_lines += 1,
            _ => self.stats.stray_replies += 1,
        }
    }

    /// The first reply of the wanted shape among the parsed ones, if any.
    fn take_reply(&mut self, want_value: bool) -> Option<Result<Option<Number>, Error>> {
        while let Some(reply) = self.parser.next_reply() {
            match reply {
                PtuReply::Value(n) if want_value => return Some(Ok(Some(n))),
                // Any `*` form acknowledges a command: verbose mode answers with sentences,
                // and some of those carry numbers.
                PtuReply::Ok | PtuReply::Info(_) | PtuReply::Value(_) if !want_value => {
                    return Some(Ok(None));
                }
                PtuReply::Error(e) => return Some(Err(Error::Ptu(e))),
                other => self.note_unsolicited(other),
            }
        }
        None
    }

    async fn await_reply(&mut self, want_value: bool, wait: Duration) -> Result<Option<Number>, Error> {
        let deadline = tokio::time::Instant::from_std(deadline_after(wait));
        let mut buf = [0u8; 256];
        loop {
            if let Some(r) = self.take_reply(want_value) {
                return r;
            }
            match timeout_at(deadline, self.link.read(&mut buf)).await {
                Err(_elapsed) => {
                    // A unit may leave its last line (the reset answer) unterminated.
                    self.parser.flush_line();
                    if let Some(r) = self.take_reply(want_value) {
                        return r;
                    }
                    self.stats.timeouts += 1;
                    return Err(Error::Timeout {
                        waiting_for: "PTU reply",
                        after: wait,
                    });
                }
                Ok(Ok(0)) => return Err(Error::Disconnected),
                Ok(Ok(n)) => self.parser.push(buf.get(..n).unwrap_or_default()),
                Ok(Err(e)) => return Err(classify_io(e)),
            }
        }
    }

    async fn steps(&mut self) -> Result<(i64, i64, PositionSample), Error> {
        let start = Instant::now();
        let pan = self.query_steps(Axis::Pan, AxisQuery::Position).await?;
        let tilt = self.query_steps(Axis::Tilt, AxisQuery::Position).await?;
        let span = start.elapsed();
        let sample = PositionSample {
            t: start + span / 2,
            span,
            pan_rad: self.cfg.pan.to_joint(self.pan.resolution.steps_to_rad(i64::from(pan))),
            tilt_rad: self
                .cfg
                .tilt
                .to_joint(self.tilt.resolution.steps_to_rad(i64::from(tilt))),
        };
        Ok((i64::from(pan), i64::from(tilt), sample))
    }

    /// The device step count for a joint angle, checked against the unit's limits.
    fn target_steps(&self, axis: Axis, joint_rad: f64) -> Result<i32, Error> {
        let info = self.axis(axis);
        let device = self.mapping(axis).to_device(joint_rad);
        info.resolution
            .rad_to_steps(device)
            .filter(|s| (info.min_steps..=info.max_steps).contains(s))
            .ok_or(Error::OutOfRange {
                quantity: match axis {
                    Axis::Pan => "pan (steps)",
                    Axis::Tilt => "tilt (steps)",
                },
                value: device / info.resolution.rad_per_step(),
                min: f64::from(info.min_steps),
                max: f64::from(info.max_steps),
            })
    }

    /// The speed in steps/s for `rad_s`: at least one step a second (a zero speed would never
    /// arrive), at most the unit's upper bound.
    fn speed_steps(&self, axis: Axis, rad_s: f64) -> Result<i32, Error> {
        let info = self.axis(axis);
        let steps = (rad_s / info.resolution.rad_per_step()).round().max(1.0);
        if steps > f64::from(info.max_speed_steps) {
            return Err(Error::OutOfRange {
                quantity: match axis {
                    Axis::Pan => "pan speed (rad/s)",
                    Axis::Tilt => "tilt speed (rad/s)",
                },
                value: rad_s,
                min: 0.0,
                max: f64::from(info.max_speed_steps) * info.resolution.rad_per_step(),
            });
        }
        Ok(steps as i32)
    }
}

impl<S: Link> PanTilt for FlirPtu<S> {
    /// The unit's reset (`r `): it recalibrates against its end stops and comes back to zero.
    async fn home(&mut self) -> Result<PositionSample, Error> {
        self.reset().await?;
        self.position().await
    }

    async fn move_to(&mut self, goal: Goal) -> Result<(), Error> {
        self.limits.check(&goal)?;
        let pan = self.target_steps(Axis::Pan, goal.pan_rad)?;
        let tilt = self.target_steps(Axis::Tilt, goal.tilt_rad)?;
        let pan_speed = self.speed_steps(Axis::Pan, goal.speed_rad_s)?;
        let tilt_speed = self.speed_steps(Axis::Tilt, goal.speed_rad_s)?;
        self.command(&PtuCommand::SetSpeed(Axis::Pan, pan_speed)).await?;
        self.command(&PtuCommand::SetSpeed(Axis::Tilt, tilt_speed)).await?;
        self.limit_hit = None;
        self.command(&PtuCommand::SetPosition(Axis::Pan, pan)).await?;
        self.command(&PtuCommand::SetPosition(Axis::Tilt, tilt)).await?;
        self.goal = Some(GoalSteps {
            pan: i64::from(pan),
            tilt: i64::from(tilt),
            min_speed: i64::from(pan_speed.min(tilt_speed)),
        });
        Ok(())
    }

    async fn position(&mut self) -> Result<PositionSample, Error> {
        Ok(self.steps().await?.2)
    }

    /// Polls `pp`/`tp` every sample period. The unit has no "moving" flag to poll, so the move
    /// has ended when both axes are on their goal step; without a goal (or if the unit was
    /// halted short of it) when the position has not changed for longer than one step takes
    /// at the commanded speed, plus a margin.
    async fn track(
        &mut self,
        samples: Option<&UnboundedSender<PositionSample>>,
        timeout: Duration,
    ) -> Result<PositionSample, Error> {
        let deadline = deadline_after(timeout);
        let mut tick = tokio::time::interval(self.cfg.sample_period);
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        let still_for = Duration::try_from_secs_f64(
            2.0 / self.goal.map_or(1.0, |g| g.min_speed.max(1) as f64) + 4.0 * self.cfg.sample_period.as_secs_f64(),
        )
        .unwrap_or(Duration::MAX);
        let mut last: Option<((i64, i64), Instant)> = None;
        loop {
            tick.tick().await;
            let (pan, tilt, s) = self.steps().await?;
            if let Some(tx) = samples {
                // A receiver that went away just does not want samples any more.
                let _ = tx.send(s);
            }
            if let Some(axis) = self.limit_hit.take() {
                self.goal = None;
                return Err(Error::Ptu(PtuError::LimitHit(axis)));
            }
            if self.goal.is_some_and(|g| g.pan == pan && g.tilt == tilt) {
                self.goal = None;
                return Ok(s);
            }
            match last {
                Some((at, since)) if at == (pan, tilt) => {
                    if s.t.saturating_duration_since(since) > still_for {
                        self.goal = None;
                        return Ok(s);
                    }
                }
                _ => last = Some(((pan, tilt), s.t)),
            }
            if Instant::now() > deadline {
                return Err(Error::Timeout {
                    waiting_for: "the move to end",
                    after: timeout,
                });
            }
        }
    }

    async fn halt(&mut self) -> Result<(), Error> {
        self.goal = None;
        self.command(&PtuCommand::Halt).await?;
        Ok(())
    }

    /// Positions and speeds. The unit has no status word: `moving` is "a move this driver
    /// started has not reached its goal", `homed` is always true (the unit calibrates at
    /// power-up), and a fault shows as a `!` answer to the next command instead.
    async fn state(&mut self) -> Result<PtuState, Error> {
        let (pan, tilt, s) = self.steps().await?;
        let pan_speed = self.query_steps(Axis::Pan, AxisQuery::Speed).await?;
        let tilt_speed = self.query_steps(Axis::Tilt, AxisQuery::Speed).await?;
        let goal = self.goal;
        let axis = |position_rad, steps: i64, speed: i32, goal: Option<i64>| AxisState {
            position_rad,
            moving: goal.is_some_and(|g| g != steps),
            homed: true,
            fault: false,
            detail: format!("{steps} steps, speed {speed} steps/s"),
        };
        Ok(PtuState {
            pan: axis(s.pan_rad, pan, pan_speed, goal.map(|g| g.pan)),
            tilt: axis(s.tilt_rad, tilt, tilt_speed, goal.map(|g| g.tilt)),
        })
    }

    fn limits(&self) -> Limits {
        self.limits
    }
}
