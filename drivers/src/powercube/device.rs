//! The async PowerCube pan-tilt unit: two modules (pan, tilt) on one serial line.
//!
//! Every exchange is: drop stale input, send one request telegram, read until the matching reply
//! ([`Request::is_reply`]) or the reply timeout, retry a bounded number of times. Telegrams that
//! are not the reply (a late answer to an earlier attempt, another module's) are skipped; a
//! corrupted reply is counted and, if no good one follows in time, retried like a lost one. A
//! module that reports ERROR in a motion acknowledgement has its CUBESTATE read and returned as
//! [`Error::DeviceFault`].

use std::path::Path;
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::mpsc::UnboundedSender;
use tokio::time::{MissedTickBehavior, timeout_at};

use super::{Command, CubeState, FrameDecoder, ModuleId, Motion, MotionTarget, Param, Reply, Request, Value};
use crate::Error;
use crate::link::{Link, SerialLink, classify_io, open_serial};
use crate::ptu::{AxisConfig, AxisState, Goal, Limits, PanTilt, PositionSample, PtuState};

/// The two axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Joint {
    Pan,
    Tilt,
}

/// Configuration of a PowerCube pan-tilt unit. The defaults are Player's: tilt module 11, pan
/// module 12, 38400 baud.
#[derive(Clone, Debug, PartialEq)]
pub struct PowerCubeConfig {
    pub pan_module: ModuleId,
    pub tilt_module: ModuleId,
    pub baud: u32,
    pub pan: AxisConfig,
    pub tilt: AxisConfig,
    /// How long to wait for one reply. A telegram takes ~3 ms at 38400 baud; the rest is slack
    /// for the module and a loaded host.
    pub reply_timeout: Duration,
    /// Extra attempts after a lost or corrupted reply.
    pub retries: u32,
    /// Position sampling period while tracking a move (20 ms = 50 Hz: two position exchanges
    /// take ~10 ms of the line at 38400 baud, leaving room for a state read).
    pub sample_period: Duration,
    /// RAMP_ACC written to both modules at start-up (rad/s²).
    pub acceleration_rad_s2: f64,
    /// Homing must end within this.
    pub home_timeout: Duration,
    /// A ramp has ended when both axes are this close to the goal and MOTION is clear.
    pub goal_tolerance_rad: f64,
}

impl Default for PowerCubeConfig {
    fn default() -> Self {
        Self {
            pan_module: ModuleId::new(12).unwrap_or_else(|| unreachable!("12 is a valid id")),
            tilt_module: ModuleId::new(11).unwrap_or_else(|| unreachable!("11 is a valid id")),
            baud: 38400,
            pan: AxisConfig::default(),
            tilt: AxisConfig::default(),
            reply_timeout: Duration::from_millis(150),
            retries: 2,
            sample_period: Duration::from_millis(20),
            acceleration_rad_s2: 1.0,
            home_timeout: Duration::from_secs(30),
            goal_tolerance_rad: 1e-3,
        }
    }
}

/// What the link has been through (for status output and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    pub exchanges: u64,
    /// Attempts repeated after a lost or corrupted reply.
    pub retries: u64,
    /// Replies that did not arrive in time.
    pub timeouts: u64,
    /// Malformed telegrams and checksum failures seen.
    pub frame_errors: u64,
    /// Well-formed telegrams that were not the awaited reply (late answers, echoes).
    pub stray_frames: u64,
}

/// A PowerCube pan-tilt unit over any byte stream.
pub struct PowerCubePtu<S> {
    link: S,
    cfg: PowerCubeConfig,
    decoder: FrameDecoder,
    limits: Limits,
    goal: Option<Goal>,
    stats: LinkStats,
}

impl PowerCubePtu<SerialLink> {
    /// Opens the serial port at `path` and starts the unit (see [`PowerCubePtu::new`]).
    pub async fn open(path: &Path, cfg: PowerCubeConfig) -> Result<Self, Error> {
        let link = open_serial(path, cfg.baud)?;
        Self::new(link, cfg).await
    }

    /// Reopens the port by the same path (after an unplug) and reads the limits again.
    pub async fn reconnect(&mut self) -> Result<(), Error> {
        let path = self.link.path().to_owned();
        self.link = open_serial(&path, self.cfg.baud)?;
        self.decoder.reset();
        self.start().await
    }
}

impl<S: Link> PowerCubePtu<S> {
    /// Starts the unit on `link`: reads both modules' limits and writes the ramp acceleration.
    /// Fails if a module does not answer. Does not reset or home (see [`PanTilt::home`]): a
    /// bring-up tool must be able to look at a faulted unit without clearing the fault.
    pub async fn new(link: S, cfg: PowerCubeConfig) -> Result<Self, Error> {
        let mut ptu = Self {
            link,
            cfg,
            decoder: FrameDecoder::new(),
            limits: Limits {
                pan_rad: (f64::NEG_INFINITY, f64::INFINITY),
                tilt_rad: (f64::NEG_INFINITY, f64::INFINITY),
            },
            goal: None,
            stats: LinkStats::default(),
        };
        ptu.start().await?;
        Ok(ptu)
    }

    async fn start(&mut self) -> Result<(), Error> {
        let acc = self.cfg.acceleration_rad_s2 as f32;
        let mut limits = [(0.0, 0.0); 2];
        for (i, joint) in [Joint::Pan, Joint::Tilt].into_iter().enumerate() {
            let min = self.get_f32(joint, Param::MinPos).await?;
            let max = self.get_f32(joint, Param::MaxPos).await?;
            limits[i] = self.axis(joint).interval_to_joint((min, max));
            self.set(joint, Param::RampAcc, Value::F32(acc)).await?;
        }
        self.limits = Limits {
            pan_rad: limits[0],
            tilt_rad: limits[1],
        };
        Ok(())
    }

    pub fn config(&self) -> &PowerCubeConfig {
        &self.cfg
    }

    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The link, e.g. to close it.
    pub fn into_inner(self) -> S {
        self.link
    }

    fn module(&self, joint: Joint) -> ModuleId {
        match joint {
            Joint::Pan => self.cfg.pan_module,
            Joint::Tilt => self.cfg.tilt_module,
        }
    }

    fn axis(&self, joint: Joint) -> AxisConfig {
        match joint {
            Joint::Pan => self.cfg.pan,
            Joint::Tilt => self.cfg.tilt,
        }
    }

    /// One request/reply exchange with retries. `Ok(None)` for a command without a reply.
    pub async fn request(&mut self, joint: Joint, command: Command) -> Result<Option<Reply>, Error> {
        let req = Request::new(self.module(joint), command);
        let wire = req.encode();
        self.stats.exchanges += 1;
        // Whatever is queued now answers nothing we are about to ask.
        while self.decoder.next_frame().is_some() {}
        let mut last = None;
        for attempt in 0..=self.cfg.retries {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            self.link.write_all(&wire).await.map_err(classify_io)?;
            self.link.flush().await.map_err(classify_io)?;
            if !command.expects_reply() {
                return Ok(None);
            }
            match self.await_reply(&req).await {
                Ok(reply) => return Ok(Some(reply)),
                Err(e) if e.is_transient() => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or(Error::Timeout {
            waiting_for: "PowerCube reply",
            after: self.cfg.reply_timeout,
        }))
    }

    /// Reads until the reply to `req` or the timeout. A corrupted telegram does not end the
    /// wait (the good reply may still follow, e.g. after garbage), but it is what we report if
    /// nothing better comes: a checksum error says more than a timeout.
    async fn await_reply(&mut self, req: &Request) -> Result<Reply, Error> {
        let deadline = tokio::time::Instant::now() + self.cfg.reply_timeout;
        let mut frame_error: Option<Error> = None;
        let mut buf = [0u8; 256];
        loop {
            while let Some(item) = self.decoder.next_frame() {
                match item {
                    Ok(frame) if req.is_reply(&frame) => {
                        return req.parse_reply(&frame).map_err(Error::from);
                    }
                    Ok(_) => self.stats.stray_frames += 1,
                    Err(e) => {
                        self.stats.frame_errors += 1;
                        frame_error = Some(e.into());
                    }
                }
            }
            match timeout_at(deadline, self.link.read(&mut buf)).await {
                Err(_elapsed) => {
                    self.stats.timeouts += 1;
                    return Err(frame_error.unwrap_or(Error::Timeout {
                        waiting_for: "PowerCube reply",
                        after: self.cfg.reply_timeout,
                    }));
                }
                Ok(Ok(0)) => return Err(Error::Disconnected),
                Ok(Ok(n)) => self.decoder.push(buf.get(..n).unwrap_or_default()),
                Ok(Err(e)) => return Err(classify_io(e)),
            }
        }
    }

    /// GET_EXT of one parameter.
    pub async fn get(&mut self, joint: Joint, param: Param) -> Result<Value, Error> {
        match self.request(joint, Command::GetExt(param)).await? {
            Some(Reply::GetExt { value, .. }) => Ok(value),
            other => Err(unexpected("GET_EXT reply", other)),
        }
    }

    async fn get_f32(&mut self, joint: Joint, param: Param) -> Result<f64, Error> {
        match self.get(joint, param).await? {
            Value::F32(v) => Ok(f64::from(v)),
            other => Err(unexpected("f32 value", Some(other))),
        }
    }

    /// SET_EXT of one parameter.
    pub async fn set(&mut self, joint: Joint, param: Param, value: Value) -> Result<(), Error> {
        self.request(joint, Command::SetExt { param, value }).await?;
        Ok(())
    }

    /// The module's CUBESTATE.
    pub async fn cube_state(&mut self, joint: Joint) -> Result<CubeState, Error> {
        match self.get(joint, Param::CubeState).await? {
            Value::U32(bits) => Ok(CubeState(bits)),
            other => Err(unexpected("u32 CUBESTATE", Some(other))),
        }
    }

    /// Joint angle of one axis.
    pub async fn joint_position(&mut self, joint: Joint) -> Result<f64, Error> {
        let device = self.get_f32(joint, Param::ActPos).await?;
        Ok(self.axis(joint).to_joint(device))
    }

    /// Joint velocity of one axis (rad/s).
    pub async fn joint_velocity(&mut self, joint: Joint) -> Result<f64, Error> {
        let device = self.get_f32(joint, Param::ActVel).await?;
        Ok(self.axis(joint).sign * device)
    }

    /// RESET both modules: clears ERROR and HALTED.
    pub async fn reset(&mut self) -> Result<(), Error> {
        for joint in [Joint::Pan, Joint::Tilt] {
            self.request(joint, Command::Reset).await?;
        }
        self.goal = None;
        Ok(())
    }

    /// Writes soft limits (joint convention) to both modules.
    pub async fn set_limits(&mut self, limits: Limits) -> Result<(), Error> {
        for (joint, (lo, hi)) in [(Joint::Pan, limits.pan_rad), (Joint::Tilt, limits.tilt_rad)] {
            let axis = self.axis(joint);
            let (a, b) = (axis.to_device(lo), axis.to_device(hi));
            self.set(joint, Param::MinPos, Value::F32(a.min(b) as f32)).await?;
            self.set(joint, Param::MaxPos, Value::F32(a.max(b) as f32)).await?;
        }
        self.limits = limits;
        Ok(())
    }

    /// Runs both axes at constant joint velocities (rad/s) until halted, a limit, or a new move.
    pub async fn velocity_move(&mut self, pan_rad_s: f64, tilt_rad_s: f64) -> Result<(), Error> {
        self.goal = None;
        for (joint, v) in [(Joint::Pan, pan_rad_s), (Joint::Tilt, tilt_rad_s)] {
            let vel_rad_s = (self.axis(joint).sign * v) as f32;
            self.motion(joint, MotionTarget::Velocity { vel_rad_s }).await?;
        }
        Ok(())
    }

    /// A with-reply motion command, so a lost command is retried like any exchange and a module
    /// in error says so at once.
    async fn motion(&mut self, joint: Joint, target: MotionTarget) -> Result<(), Error> {
        let cmd = Command::SetMotion(Motion {
            target,
            with_reply: true,
        });
        match self.request(joint, cmd).await? {
            Some(Reply::MotionAck { state, .. }) if state.is_error() => {
                let state = self.cube_state(joint).await?;
                Err(Error::DeviceFault {
                    module: self.module(joint),
                    state,
                })
            }
            Some(Reply::MotionAck { .. } | Reply::Motion { .. }) => Ok(()),
            other => Err(unexpected("motion acknowledgement", other)),
        }
    }

    /// Both CUBESTATEs; a fault becomes [`Error::DeviceFault`].
    async fn check_faults(&mut self) -> Result<[CubeState; 2], Error> {
        let mut out = [CubeState(0); 2];
        for (i, joint) in [Joint::Pan, Joint::Tilt].into_iter().enumerate() {
            let state = self.cube_state(joint).await?;
            if state.is_fault() {
                return Err(Error::DeviceFault {
                    module: self.module(joint),
                    state,
                });
            }
            out[i] = state;
        }
        Ok(out)
    }

    async fn sample(&mut self) -> Result<PositionSample, Error> {
        let start = Instant::now();
        let pan_rad = self.joint_position(Joint::Pan).await?;
        let tilt_rad = self.joint_position(Joint::Tilt).await?;
        let span = start.elapsed();
        Ok(PositionSample {
            t: start + span / 2,
            span,
            pan_rad,
            tilt_rad,
        })
    }

    fn near_goal(&self, s: &PositionSample) -> bool {
        self.goal.is_none_or(|g| {
            (s.pan_rad - g.pan_rad).abs() <= self.cfg.goal_tolerance_rad
                && (s.tilt_rad - g.tilt_rad).abs() <= self.cfg.goal_tolerance_rad
        })
    }
}

fn unexpected<T: std::fmt::Debug>(expected: &'static str, got: Option<T>) -> Error {
    Error::Protocol {
        expected,
        got: format!("{got:?}"),
    }
}

/// CUBESTATE as a protocol-neutral axis state.
fn axis_state(position_rad: f64, s: CubeState) -> AxisState {
    AxisState {
        position_rad,
        moving: s.is_moving(),
        homed: s.is_homed(),
        fault: s.is_fault() || s.contains(CubeState::HALTED),
        detail: s.to_string(),
    }
}

impl<S: Link> PanTilt for PowerCubePtu<S> {
    /// RESET, HOME, then poll CUBESTATE until both modules report HOME_OK and stand still, as
    /// Player starts its PowerCube unit.
    async fn home(&mut self) -> Result<PositionSample, Error> {
        self.reset().await?;
        for joint in [Joint::Pan, Joint::Tilt] {
            self.request(joint, Command::Home).await?;
        }
        let deadline = Instant::now() + self.cfg.home_timeout;
        let mut tick = tokio::time::interval(self.cfg.sample_period);
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            let [pan, tilt] = self.check_faults().await?;
            if pan.is_homed() && tilt.is_homed() && !pan.is_moving() && !tilt.is_moving() {
                return self.sample().await;
            }
            if Instant::now() > deadline {
                return Err(Error::Timeout {
                    waiting_for: "HOME_OK on both modules",
                    after: self.cfg.home_timeout,
                });
            }
        }
    }

    async fn move_to(&mut self, goal: Goal) -> Result<(), Error> {
        self.limits.check(&goal)?;
        for (joint, target) in [(Joint::Pan, goal.pan_rad), (Joint::Tilt, goal.tilt_rad)] {
            self.set(joint, Param::RampVel, Value::F32(goal.speed_rad_s as f32))
                .await?;
            let pos_rad = self.axis(joint).to_device(target) as f32;
            self.motion(joint, MotionTarget::Ramp { pos_rad }).await?;
        }
        self.goal = Some(goal);
        Ok(())
    }

    async fn position(&mut self) -> Result<PositionSample, Error> {
        self.sample().await
    }

    /// Samples both positions every `sample_period`. CUBESTATE is read only near the goal (to
    /// confirm the ramp ended) and every tenth sample (to catch a fault or a halt), so most of
    /// the line's time goes to positions.
    async fn track(
        &mut self,
        samples: Option<&UnboundedSender<PositionSample>>,
        timeout: Duration,
    ) -> Result<PositionSample, Error> {
        let deadline = Instant::now() + timeout;
        let mut tick = tokio::time::interval(self.cfg.sample_period);
        tick.set_missed_tick_behavior(MissedTickBehavior::Delay);
        for n in 0u64.. {
            tick.tick().await;
            let s = self.sample().await?;
            if let Some(tx) = samples {
                // A receiver that went away just does not want samples any more.
                let _ = tx.send(s);
            }
            if self.near_goal(&s) || n % 10 == 9 {
                let [pan, tilt] = self.check_faults().await?;
                let halted = pan.contains(CubeState::HALTED) || tilt.contains(CubeState::HALTED);
                if halted || (self.near_goal(&s) && !pan.is_moving() && !tilt.is_moving()) {
                    self.goal = None;
                    return Ok(s);
                }
            }
            if Instant::now() > deadline {
                return Err(Error::Timeout {
                    waiting_for: "the move to end",
                    after: timeout,
                });
            }
        }
        unreachable!("the sample loop only ends by returning")
    }

    async fn halt(&mut self) -> Result<(), Error> {
        self.goal = None;
        for joint in [Joint::Pan, Joint::Tilt] {
            self.request(joint, Command::Halt).await?;
        }
        Ok(())
    }

    async fn state(&mut self) -> Result<PtuState, Error> {
        let s = self.sample().await?;
        let pan = self.cube_state(Joint::Pan).await?;
        let tilt = self.cube_state(Joint::Tilt).await?;
        Ok(PtuState {
            pan: axis_state(s.pan_rad, pan),
            tilt: axis_state(s.tilt_rad, tilt),
        })
    }

    fn limits(&self) -> Limits {
        self.limits
    }
}
