//! FLIR / Directed Perception PTU-D46 family, ASCII protocol.
//!
//! - [`command`]: [`PtuCommand`] formatting (each command ends with a space).
//! - [`reply`]: the incremental [`ReplyParser`] for `*`, `* <value>`, `! <message>`, `!P`/`!T`,
//!   echo, verbose sentences and noise.
//! - [`Resolution`]: steps <-> radians.
//! - [`device`]: the async [`FlirPtu`] over any byte stream.

pub mod command;
pub mod device;
pub mod reply;

pub use command::{Axis, AxisQuery, PtuCommand};
pub use device::{FlirAxisInfo, FlirConfig, FlirPtu, FlirStats};
pub use reply::{Number, PtuError, PtuReply, ReplyParser};

/// Arc-seconds in a radian.
const ARCSEC_PER_RAD: f64 = 180.0 * 3600.0 / std::f64::consts::PI;

/// An axis resolution, as `pr` / `tr` report it: arc-seconds per step (model dependent, e.g.
/// 185.1428 arcsec = 0.0514 deg per step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolution {
    arcsec_per_step: f64,
}

impl Resolution {
    /// `None` unless finite and positive.
    pub fn from_arcsec_per_step(arcsec_per_step: f64) -> Option<Self> {
        (arcsec_per_step.is_finite() && arcsec_per_step > 0.0).then_some(Self { arcsec_per_step })
    }

    pub fn arcsec_per_step(self) -> f64 {
        self.arcsec_per_step
    }

    pub fn deg_per_step(self) -> f64 {
        self.arcsec_per_step / 3600.0
    }

    pub fn rad_per_step(self) -> f64 {
        self.arcsec_per_step / ARCSEC_PER_RAD
    }

    /// Joint angle of a step count.
    pub fn steps_to_rad(self, steps: i64) -> f64 {
        steps as f64 * self.rad_per_step()
    }

    /// Nearest step count for an angle; `None` if the angle is not finite or does not fit an
    /// i32 (the unit's own limits, `pn`/`px`, are far smaller: check against those too).
    pub fn rad_to_steps(self, rad: f64) -> Option<i32> {
        let steps = (rad / self.rad_per_step()).round();
        (steps.is_finite() && steps >= f64::from(i32::MIN) && steps <= f64::from(i32::MAX)).then_some(steps as i32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_conversions() {
        let r = Resolution::from_arcsec_per_step(185.1428).unwrap();
        assert!((r.deg_per_step() - 0.051_428_56).abs() < 1e-8);
        // The manual's pan limit 3090 steps is about 158.9 degrees.
        assert!((r.steps_to_rad(3090).to_degrees() - 158.914).abs() < 1e-3);
        assert_eq!(r.rad_to_steps(r.steps_to_rad(-907)), Some(-907));
        assert_eq!(r.rad_to_steps(0.0514_f64.to_radians() * 10.4), Some(10));
        assert_eq!(r.rad_to_steps(f64::NAN), None);
        assert_eq!(r.rad_to_steps(1e12), None);
        assert!(Resolution::from_arcsec_per_step(0.0).is_none());
        assert!(Resolution::from_arcsec_per_step(f64::INFINITY).is_none());
    }
}
