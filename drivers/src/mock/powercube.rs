//! A mock PowerCube pan-tilt unit, written from the modules' side.
//!
//! Two modules on one line, each a small state machine with its own kinematics: ramps bounded
//! by the smaller of RAMP_VEL/MAX_VEL and RAMP_ACC/MAX_ACC, velocity moves, soft limits, homing
//! to zero, HALT, RESET and the CUBESTATE bits. Time is whatever `now` the caller passes; the
//! joints are integrated up to it on every request, so a process using the wall clock behaves
//! like hardware and a test can step time by hand.
//!
//! It uses the codec to find telegrams in the byte stream and to parse commands (the shared
//! part), but its behaviour — what a module does and answers — is its own, so it checks the
//! driver rather than mirroring it.

use std::time::{Duration, Instant};

use super::MockDevice;
use crate::powercube::{
    Command, CubeState, Direction, Frame, FrameDecoder, ModuleId, MotionTarget, Param, Reply, ShortState, Value,
    player_bcc, schunk_bcc,
};

/// Integration step (s): fine enough that a ramp ends within micro-radians of its target.
const STEP_S: f64 = 1e-3;

/// One simulated module's fixed properties.
#[derive(Clone, Debug, PartialEq)]
pub struct MockModuleConfig {
    pub id: ModuleId,
    /// Position at power-up (rad): not homed, not necessarily zero.
    pub initial_rad: f64,
    pub min_rad: f64,
    pub max_rad: f64,
    pub max_vel_rad_s: f64,
    pub max_acc_rad_s2: f64,
}

/// The mock unit's configuration: Player's module ids, limits of a typical PW-70 wrist.
#[derive(Clone, Debug, PartialEq)]
pub struct MockPowerCubeConfig {
    pub pan: MockModuleConfig,
    pub tilt: MockModuleConfig,
}

impl Default for MockPowerCubeConfig {
    fn default() -> Self {
        let id = |n| ModuleId::new(n).unwrap_or_else(|| unreachable!("valid id"));
        Self {
            pan: MockModuleConfig {
                id: id(12),
                initial_rad: 0.0,
                min_rad: -2.9,
                max_rad: 2.9,
                max_vel_rad_s: 1.5,
                max_acc_rad_s2: 4.0,
            },
            tilt: MockModuleConfig {
                id: id(11),
                initial_rad: 0.0,
                min_rad: -1.5,
                max_rad: 1.5,
                max_vel_rad_s: 1.5,
                max_acc_rad_s2: 4.0,
            },
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Drive {
    Idle,
    Ramp { target: f64 },
    Velocity { vel: f64 },
    Homing,
}

/// One module.
#[derive(Clone, Debug)]
pub struct MockModule {
    cfg: MockModuleConfig,
    pos: f64,
    vel: f64,
    drive: Drive,
    min: f64,
    max: f64,
    ramp_vel: f64,
    ramp_acc: f64,
    state: u32,
    at: Option<Instant>,
}

impl MockModule {
    pub fn new(cfg: MockModuleConfig) -> Self {
        Self {
            pos: cfg.initial_rad,
            vel: 0.0,
            drive: Drive::Idle,
            min: cfg.min_rad,
            max: cfg.max_rad,
            ramp_vel: cfg.max_vel_rad_s * 0.5,
            ramp_acc: cfg.max_acc_rad_s2 * 0.5,
            state: 0,
            at: None,
            cfg,
        }
    }

    pub fn id(&self) -> ModuleId {
        self.cfg.id
    }

    /// Position (rad) after integrating up to `now`.
    pub fn position(&mut self, now: Instant) -> f64 {
        self.advance(now);
        self.pos
    }

    pub fn cube_state(&self) -> CubeState {
        CubeState(self.state)
    }

    fn set_bit(&mut self, bit: u32, on: bool) {
        if on {
            self.state |= bit;
        } else {
            self.state &= !bit;
        }
    }

    fn blocked(&self) -> bool {
        self.state & (CubeState::ERROR | CubeState::HALTED) != 0
    }

    /// Integrates the motion up to `now` in fixed steps.
    fn advance(&mut self, now: Instant) {
        let Some(mut at) = self.at else {
            self.at = Some(now);
            return;
        };
        let step = Duration::from_secs_f64(STEP_S);
        while at + step <= now {
            at += step;
            self.step(STEP_S);
            if self.drive == Drive::Idle {
                at = now;
                break;
            }
        }
        self.at = Some(at);
    }

    fn step(&mut self, dt: f64) {
        let acc = self.ramp_acc.min(self.cfg.max_acc_rad_s2);
        let vmax = self.ramp_vel.min(self.cfg.max_vel_rad_s);
        let v_want = match self.drive {
            Drive::Idle => return,
            Drive::Velocity { vel } => vel.clamp(-self.cfg.max_vel_rad_s, self.cfg.max_vel_rad_s),
            Drive::Ramp { target } => match self.ramp_speed(target, acc, vmax, dt) {
                Some(v) => v,
                None => return,
            },
            Drive::Homing => match self.ramp_speed(0.0, acc, vmax, dt) {
                Some(v) => v,
                None => return,
            },
        };
        let dv = (v_want - self.vel).clamp(-acc * dt, acc * dt);
        self.vel += dv;
        let target = match self.drive {
            Drive::Ramp { target } => Some(target),
            Drive::Homing => Some(0.0),
            _ => None,
        };
        if let Some(target) = target
            && (target - self.pos) * self.vel >= 0.0
            && (target - self.pos).abs() <= (self.vel * dt).abs()
        {
            // This step reaches the target: end the ramp on it instead of overshooting.
            self.pos = target;
            self.vel = 0.0;
            self.finish();
            return;
        }
        self.pos += self.vel * dt;
        if self.pos < self.min || self.pos > self.max {
            // Soft limit: stop on it, as the module's own controller does.
            self.pos = self.pos.clamp(self.min, self.max);
            self.vel = 0.0;
            self.finish();
        }
    }

    /// The speed a ramp to `target` wants now: the fastest from which it can still stop at the
    /// target, at most `vmax`. `None` once it has arrived (and the ramp is finished).
    fn ramp_speed(&mut self, target: f64, acc: f64, vmax: f64, dt: f64) -> Option<f64> {
        let d = target - self.pos;
        if d.abs() < 1e-6 && self.vel.abs() <= 2.0 * acc * dt {
            self.pos = target;
            self.vel = 0.0;
            self.finish();
            return None;
        }
        Some(d.signum() * vmax.min((2.0 * acc * d.abs()).sqrt()))
    }

    fn finish(&mut self) {
        if self.drive == Drive::Homing {
            self.set_bit(CubeState::HOME_OK, true);
        }
        self.drive = Drive::Idle;
        self.set_bit(CubeState::MOTION, false);
        self.set_bit(CubeState::RAMP_END, true);
    }

    fn start(&mut self, drive: Drive) {
        self.drive = drive;
        self.set_bit(CubeState::MOTION, true);
        self.set_bit(CubeState::RAMP_END, false);
    }

    fn short_state(&self) -> ShortState {
        let mut s = 0;
        if self.blocked() {
            s |= ShortState::ERROR;
        }
        if self.state & CubeState::MOTION != 0 {
            s |= ShortState::MOTION | ShortState::IN_PROGRESS;
        }
        if self.state & CubeState::RAMP_END != 0 {
            s |= ShortState::RAMP_END;
        }
        ShortState(s)
    }

    /// Executes one command at `now`; `None` when the module stays silent.
    pub fn execute(&mut self, command: Command, now: Instant) -> Option<Reply> {
        self.advance(now);
        let ack = Reply::Ack {
            command: command.code(),
        };
        match command {
            Command::Reset => {
                self.set_bit(CubeState::ERROR | CubeState::HALTED, false);
                Some(ack)
            }
            Command::Home => {
                if !self.blocked() {
                    self.set_bit(CubeState::HOME_OK, false);
                    self.start(Drive::Homing);
                }
                Some(ack)
            }
            Command::Halt => {
                self.vel = 0.0;
                self.drive = Drive::Idle;
                self.set_bit(CubeState::MOTION, false);
                self.set_bit(CubeState::HALTED, true);
                Some(ack)
            }
            Command::Watchdog | Command::StartMove | Command::ResetTime => Some(ack),
            Command::GetExt(param) => Some(Reply::GetExt {
                param,
                value: self.read(param),
            }),
            Command::SetExt { param, value } => {
                self.write(param, value);
                Some(Reply::SetExt { param })
            }
            Command::SetMotion(m) => {
                if !self.blocked() {
                    match m.target {
                        MotionTarget::Ramp { pos_rad } | MotionTarget::Step { pos_rad, .. } => {
                            let target = f64::from(pos_rad).clamp(self.min, self.max);
                            self.start(Drive::Ramp { target });
                        }
                        MotionTarget::Velocity { vel_rad_s } => {
                            self.start(Drive::Velocity {
                                vel: f64::from(vel_rad_s),
                            });
                        }
                    }
                }
                m.with_reply.then(|| Reply::MotionAck {
                    mode: m.mode(),
                    pos_rad: self.pos as f32,
                    state: self.short_state(),
                    dio: 0,
                })
            }
        }
    }

    fn read(&self, param: Param) -> Value {
        let f = |v: f64| Value::F32(v as f32);
        match param {
            Param::Version => Value::U16(0x3512),
            Param::CubeState => Value::U32(self.state),
            Param::ActPos => f(self.pos),
            Param::ActVel => f(self.vel),
            Param::MinPos => f(self.min),
            Param::MaxPos => f(self.max),
            Param::MaxVel => f(self.cfg.max_vel_rad_s),
            Param::MaxAcc => f(self.cfg.max_acc_rad_s2),
            Param::RampVel => f(self.ramp_vel),
            Param::RampAcc => f(self.ramp_acc),
        }
    }

    /// Writes a parameter; nonsense values (not finite, not positive where a speed is meant)
    /// are ignored, as a module keeps its last good setting.
    fn write(&mut self, param: Param, value: Value) {
        let Some(v) = value.as_f32().map(f64::from).filter(|v| v.is_finite()) else {
            return;
        };
        match param {
            Param::MinPos if v < self.max => self.min = v,
            Param::MaxPos if v > self.min => self.max = v,
            Param::RampVel if v > 0.0 => self.ramp_vel = v,
            Param::RampAcc if v > 0.0 => self.ramp_acc = v,
            _ => {}
        }
    }
}

/// The mock unit: two modules on one line.
#[derive(Debug)]
pub struct MockPowerCube {
    pan: MockModule,
    tilt: MockModule,
    decoder: FrameDecoder,
    /// Request telegrams that failed to decode (a real module ignores them).
    pub bad_requests: u64,
}

impl MockPowerCube {
    pub fn new(cfg: MockPowerCubeConfig) -> Self {
        Self {
            pan: MockModule::new(cfg.pan),
            tilt: MockModule::new(cfg.tilt),
            decoder: FrameDecoder::new(),
            bad_requests: 0,
        }
    }

    pub fn pan(&mut self) -> &mut MockModule {
        &mut self.pan
    }

    pub fn tilt(&mut self) -> &mut MockModule {
        &mut self.tilt
    }

    /// The answer to one request telegram, if any module answers it.
    fn answer(&mut self, frame: &Frame, now: Instant) -> Option<Vec<u8>> {
        if frame.direction != Direction::ToModule {
            return None;
        }
        let module = [&mut self.pan, &mut self.tilt]
            .into_iter()
            .find(|m| m.id() == frame.module)?;
        let Ok(command) = Command::parse(frame.data.as_slice()) else {
            // A real module ignores what it cannot parse; the driver times out and retries.
            self.bad_requests += 1;
            return None;
        };
        let reply = module.execute(command, now)?;
        Some(Frame::reply(frame.module, reply.payload()).encode())
    }
}

impl MockDevice for MockPowerCube {
    fn receive(&mut self, bytes: &[u8], now: Instant) -> Vec<Vec<u8>> {
        self.decoder.push(bytes);
        let mut out = Vec::new();
        while let Some(item) = self.decoder.next_frame() {
            match item {
                Ok(frame) => out.extend(self.answer(&frame, now)),
                Err(_) => self.bad_requests += 1,
            }
        }
        out
    }

    /// Re-frames the telegram with a BCC that matches neither checksum form.
    fn corrupt(&self, reply: &[u8]) -> Vec<u8> {
        let mut d = FrameDecoder::new();
        d.push(reply);
        let Some(Ok(frame)) = d.next_frame() else {
            return reply.to_vec();
        };
        let telid = frame.telid();
        let data = frame.data.as_slice();
        let good = [schunk_bcc(telid, data), player_bcc(frame.module, data)];
        let bad = (1..=255u8)
            .map(|k| good[0].wrapping_add(k))
            .find(|b| !good.contains(b))
            .unwrap_or(0);
        let mut out = vec![0x02];
        for &b in telid.iter().chain(data).chain(std::iter::once(&bad)) {
            if matches!(b, 0x02 | 0x03 | 0x10) {
                out.extend([0x10, b.wrapping_add(0x80)]);
            } else {
                out.push(b);
            }
        }
        out.push(0x03);
        out
    }

    fn joint_angles(&mut self, now: Instant) -> (f64, f64) {
        (self.pan.position(now), self.tilt.position(now))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::powercube::{Motion, Request};

    fn ask(m: &mut MockPowerCube, req: Request, now: Instant) -> Option<Reply> {
        let out = m.receive(&req.encode(), now);
        let wire = out.first()?;
        let mut d = FrameDecoder::new();
        d.push(wire);
        let frame = d.next_frame()?.ok()?;
        req.parse_reply(&frame).ok()
    }

    fn ramp(pos_rad: f32) -> Command {
        Command::SetMotion(Motion {
            target: MotionTarget::Ramp { pos_rad },
            with_reply: true,
        })
    }

    #[test]
    fn ramp_respects_velocity_and_acceleration_and_ends_on_target() {
        let mut m = MockPowerCube::new(MockPowerCubeConfig::default());
        let tilt = m.tilt.id();
        let t0 = Instant::now();
        let set = |param, v| Command::SetExt {
            param,
            value: Value::F32(v),
        };
        ask(&mut m, Request::new(tilt, set(Param::RampVel, 0.5)), t0);
        ask(&mut m, Request::new(tilt, set(Param::RampAcc, 1.0)), t0);
        let ack = ask(&mut m, Request::new(tilt, ramp(1.0)), t0).unwrap();
        assert!(matches!(ack, Reply::MotionAck { state, .. } if state.is_moving()));
        // Trapezoid: 0.5 s up (0.125 rad), 1.5 s cruise (0.75 rad), 0.5 s down: 2.5 s in all.
        let mut prev = 0.0;
        for k in 1..=30 {
            let t = t0 + Duration::from_millis(100 * k);
            let p = m.tilt.position(t);
            let v = (p - prev) / 0.1;
            assert!(v <= 0.5 + 1e-6, "speed {v} at {k}");
            if k == 5 {
                assert!((p - 0.125).abs() < 2e-3, "{p} after the acceleration phase");
            }
            prev = p;
        }
        assert_eq!(m.tilt.position(t0 + Duration::from_secs(3)), 1.0);
        let state = m.tilt.cube_state();
        assert!(!state.is_moving() && state.contains(CubeState::RAMP_END));
    }

    #[test]
    fn halt_blocks_motion_until_reset_and_home_sets_home_ok() {
        let mut m = MockPowerCube::new(MockPowerCubeConfig::default());
        let pan = m.pan.id();
        let t0 = Instant::now();
        ask(&mut m, Request::new(pan, Command::Halt), t0);
        let ack = ask(&mut m, Request::new(pan, ramp(0.5)), t0).unwrap();
        assert!(matches!(ack, Reply::MotionAck { state, .. } if state.is_error()));
        assert_eq!(m.pan.position(t0 + Duration::from_secs(1)), 0.0);
        ask(&mut m, Request::new(pan, Command::Reset), t0);
        ask(&mut m, Request::new(pan, ramp(0.5)), t0);
        assert_eq!(m.pan.position(t0 + Duration::from_secs(5)), 0.5);
        ask(&mut m, Request::new(pan, Command::Home), t0 + Duration::from_secs(5));
        assert!(!m.pan.cube_state().is_homed());
        assert_eq!(m.pan.position(t0 + Duration::from_secs(10)), 0.0);
        assert!(m.pan.cube_state().is_homed());
    }

    #[test]
    fn targets_are_clamped_to_soft_limits_and_unknown_modules_are_silent() {
        let mut m = MockPowerCube::new(MockPowerCubeConfig::default());
        let tilt = m.tilt.id();
        let t0 = Instant::now();
        ask(&mut m, Request::new(tilt, ramp(9.0)), t0);
        assert_eq!(m.tilt.position(t0 + Duration::from_secs(20)), 1.5);
        let nobody = ModuleId::new(5).unwrap();
        assert!(m.receive(&Request::new(nobody, Command::Reset).encode(), t0).is_empty());
    }

    #[test]
    fn corrupted_reply_fails_its_checksum() {
        let m = MockPowerCube::new(MockPowerCubeConfig::default());
        let good = Frame::reply(m.pan.id(), Reply::Ack { command: 0 }.payload()).encode();
        let mut d = FrameDecoder::new();
        d.push(&m.corrupt(&good));
        assert!(matches!(d.next_frame(), Some(Err(e)) if e.is_checksum()));
    }
}
