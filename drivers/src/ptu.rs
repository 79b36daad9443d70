//! The one async pan-tilt interface over every PTU protocol, and the types it speaks.
//!
//! Angles are SI radians in the *joint* convention of the rig: positive pan turns left (about
//! +z), positive tilt pitches the sensor down (REP-103 pitch about +y). A device's own angles
//! map to joint angles through an [`AxisConfig`] per axis (sign and zero offset), which is
//! calibration: Player, for one, flips the sign of the PowerCube pan module.

use std::future::Future;
use std::time::{Duration, Instant};

use tokio::sync::mpsc::UnboundedSender;

use crate::Error;

/// How one device axis maps to the joint: `joint_rad = sign * device_rad + offset_rad`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisConfig {
    /// +1 or -1.
    pub sign: f64,
    /// The joint angle at the device's zero (rad).
    pub offset_rad: f64,
}

impl Default for AxisConfig {
    fn default() -> Self {
        Self {
            sign: 1.0,
            offset_rad: 0.0,
        }
    }
}

impl AxisConfig {
    /// A validated axis mapping; `sign` must be +1 or -1.
    pub fn new(sign: f64, offset_rad: f64) -> Result<Self, Error> {
        if sign != 1.0 && sign != -1.0 {
            return Err(Error::OutOfRange {
                quantity: "axis sign",
                value: sign,
                min: -1.0,
                max: 1.0,
            });
        }
        if !offset_rad.is_finite() {
            return Err(Error::OutOfRange {
                quantity: "axis offset (rad)",
                value: offset_rad,
                min: f64::MIN,
                max: f64::MAX,
            });
        }
        Ok(Self { sign, offset_rad })
    }

    pub fn to_joint(&self, device_rad: f64) -> f64 {
        self.sign * device_rad + self.offset_rad
    }

    pub fn to_device(&self, joint_rad: f64) -> f64 {
        // sign is +-1, its own inverse.
        self.sign * (joint_rad - self.offset_rad)
    }

    /// A joint-angle interval from a device-angle interval (the sign may swap the ends).
    pub fn interval_to_joint(&self, device: (f64, f64)) -> (f64, f64) {
        let (a, b) = (self.to_joint(device.0), self.to_joint(device.1));
        (a.min(b), a.max(b))
    }
}

/// Both joint angles read at (about) one instant.
///
/// `t` is host monotonic time at the midpoint between sending the first position request and
/// receiving the last reply, so a sample's stamp is off by at most half of `span` (for the
/// PowerCube at 38400 baud two exchanges take about 10 ms). The sweep assembler interpolates the
/// joint angle of each profile between the two samples bracketing its timestamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionSample {
    pub t: Instant,
    /// How long reading both axes took.
    pub span: Duration,
    pub pan_rad: f64,
    pub tilt_rad: f64,
}

/// Where to go and how fast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Goal {
    pub pan_rad: f64,
    pub tilt_rad: f64,
    /// Speed of each axis (rad/s); the device's own acceleration applies.
    pub speed_rad_s: f64,
}

/// One axis' status, common to every protocol.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisState {
    pub position_rad: f64,
    pub moving: bool,
    /// Reference position found (PowerCube HOME_OK; always true for a PTU that homes at reset).
    pub homed: bool,
    /// The axis needs a reset before it moves again.
    pub fault: bool,
    /// The device's own status words, for people: e.g. `HOME_OK|RAMP_END`.
    pub detail: String,
}

/// Status of both axes.
#[derive(Clone, Debug, PartialEq)]
pub struct PtuState {
    pub pan: AxisState,
    pub tilt: AxisState,
}

/// Joint limits (rad), in the joint convention.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub pan_rad: (f64, f64),
    pub tilt_rad: (f64, f64),
}

impl Limits {
    /// Refuses a goal outside the limits, naming the axis.
    pub fn check(&self, goal: &Goal) -> Result<(), Error> {
        for (quantity, value, (min, max)) in [
            ("pan (rad)", goal.pan_rad, self.pan_rad),
            ("tilt (rad)", goal.tilt_rad, self.tilt_rad),
        ] {
            if !(value >= min && value <= max) {
                return Err(Error::OutOfRange {
                    quantity,
                    value,
                    min,
                    max,
                });
            }
        }
        if !(goal.speed_rad_s.is_finite() && goal.speed_rad_s > 0.0) {
            return Err(Error::OutOfRange {
                quantity: "speed (rad/s)",
                value: goal.speed_rad_s,
                min: 0.0,
                max: f64::MAX,
            });
        }
        Ok(())
    }
}

/// A pan-tilt unit, whatever its protocol.
///
/// Every call is one or more request/reply exchanges with a per-reply timeout and a bounded
/// retry of a lost or corrupted reply; the error says which of timeout, framing/checksum,
/// device fault, disconnection or IO ended it.
pub trait PanTilt: Send {
    /// Brings the unit to its reference position (clearing faults first) and waits for it.
    fn home(&mut self) -> impl Future<Output = Result<PositionSample, Error>> + Send;

    /// Starts a move to `goal` and returns once the unit has accepted it (does not wait).
    fn move_to(&mut self, goal: Goal) -> impl Future<Output = Result<(), Error>> + Send;

    /// Reads both joint angles now.
    fn position(&mut self) -> impl Future<Output = Result<PositionSample, Error>> + Send;

    /// Polls the position at the driver's sample rate until the current move has ended (or
    /// `timeout` passed), sending every sample to `samples`, and returns the last one. A fault
    /// during the move ends it with [`Error::DeviceFault`] (or the protocol's equivalent).
    fn track(
        &mut self,
        samples: Option<&UnboundedSender<PositionSample>>,
        timeout: Duration,
    ) -> impl Future<Output = Result<PositionSample, Error>> + Send;

    /// Stops both axes now.
    fn halt(&mut self) -> impl Future<Output = Result<(), Error>> + Send;

    /// Reads both axes' status.
    fn state(&mut self) -> impl Future<Output = Result<PtuState, Error>> + Send;

    /// The joint limits the driver enforces (read from the device at start-up).
    fn limits(&self) -> Limits;

    /// [`move_to`](Self::move_to), then [`track`](Self::track) until it has ended.
    fn move_and_track(
        &mut self,
        goal: Goal,
        samples: Option<&UnboundedSender<PositionSample>>,
        timeout: Duration,
    ) -> impl Future<Output = Result<PositionSample, Error>> + Send
    where
        Self: Sized,
    {
        async move {
            self.move_to(goal).await?;
            self.track(samples, timeout).await
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_mapping_round_trips_and_flips_intervals() {
        let a = AxisConfig::new(-1.0, 0.1).unwrap();
        assert!((a.to_device(a.to_joint(0.7)) - 0.7).abs() < 1e-15);
        assert_eq!(a.to_joint(0.5), -0.4);
        assert_eq!(a.interval_to_joint((-1.0, 2.0)), (-1.9, 1.1));
        assert!(AxisConfig::new(2.0, 0.0).is_err());
    }

    #[test]
    fn limits_name_the_axis() {
        let l = Limits {
            pan_rad: (-1.0, 1.0),
            tilt_rad: (-0.5, 0.5),
        };
        let goal = Goal {
            pan_rad: 0.0,
            tilt_rad: 0.7,
            speed_rad_s: 0.1,
        };
        let e = l.check(&goal).unwrap_err();
        assert!(e.to_string().contains("tilt"), "{e}");
        assert!(l.check(&Goal { tilt_rad: 0.2, ..goal }).is_ok());
        assert!(
            l.check(&Goal {
                tilt_rad: f64::NAN,
                ..goal
            })
            .is_err()
        );
    }
}
