//! The parallel-jaw gripper grasps are planned for: its sizes, its friction and where the arm
//! can bring it from, as the `[gripper]` table of the configuration gives them.

use serde::Deserialize;

/// A parallel-jaw gripper. A grasp's frame sits midway between the finger pads: x is the
/// closing direction, z the approach (from the palm towards the object), y across the fingers.
///
/// The fingers are boxes `finger_thickness` (x) by `finger_width` (y) by `finger_depth` (z),
/// their tips `pad_from_tip` beyond the grasp's origin along z; the palm is a box `palm` (x, y,
/// z) right behind the fingers' roots. The defaults are a Robotiq 2F-85-class gripper.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Gripper {
    /// Widest opening between the pads (m).
    pub max_opening: f64,
    /// Narrowest opening the fingers can hold an object at (m).
    pub min_opening: f64,
    /// Length of a finger from the palm to its tip (m).
    pub finger_depth: f64,
    /// A finger's size across the closing direction (m).
    pub finger_width: f64,
    /// A finger's size along the closing direction (m).
    pub finger_thickness: f64,
    /// How far the fingertips reach past the pads' centre, the grasp's origin (m).
    pub pad_from_tip: f64,
    /// The palm's size along x, y and z (m).
    pub palm: [f64; 3],
    /// Coulomb friction coefficient of pad on object: a contact holds where the surface normal
    /// lies within atan(friction) of the closing line.
    pub friction: f64,
    /// Largest angle between the approach and straight down (against the support plane's
    /// normal, else the cloud's -z) the arm can reach (rad): pi/2 allows approaches from above
    /// down to horizontal, pi from anywhere.
    pub max_tilt: f64,
    /// The pre-grasp pose lies this far back along the approach (m); the gripper moves from it
    /// to the grasp in a straight line, open.
    pub pregrasp: f64,
    /// Least distance kept from every scene point that is not the object's and from the support
    /// plane (m); the fingers open this much wider than the object while they approach.
    pub clearance: f64,
    /// The wall thickness assumed for a grasp across the rim of an open container (m): the
    /// model is the outer surface only.
    pub wall: f64,
    /// Treat the space the sensor could not see (behind what it saw, outside the object's
    /// model) as occupied: grasps then keep the gripper where the sensor saw free space.
    pub occupy_unseen: bool,
}

impl Default for Gripper {
    fn default() -> Gripper {
        Gripper {
            max_opening: 0.085,
            min_opening: 0.0,
            finger_depth: 0.045,
            finger_width: 0.022,
            finger_thickness: 0.010,
            pad_from_tip: 0.010,
            palm: [0.120, 0.050, 0.060],
            friction: 0.4,
            max_tilt: std::f64::consts::FRAC_PI_2,
            pregrasp: 0.10,
            clearance: 0.005,
            wall: 0.004,
            occupy_unseen: false,
        }
    }
}

/// What is wrong with a gripper's settings.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GripperError {
    #[error("gripper.{field} = {value}: {why}")]
    Field {
        field: &'static str,
        value: f64,
        why: &'static str,
    },
}

/// Sizes beyond this (m) are no hand-held gripper's.
const MAX_SIZE: f64 = 2.0;

impl Gripper {
    /// Every value finite and in range, the opening range not empty, the pads on the fingers.
    pub fn validate(&self) -> Result<(), GripperError> {
        let field = |field: &'static str, value: f64, why: &'static str| Err(GripperError::Field { field, value, why });
        let sizes = [
            ("max_opening", self.max_opening),
            ("finger_depth", self.finger_depth),
            ("finger_width", self.finger_width),
            ("finger_thickness", self.finger_thickness),
            ("palm[0]", self.palm[0]),
            ("palm[1]", self.palm[1]),
            ("palm[2]", self.palm[2]),
        ];
        for (name, v) in sizes {
            if !(v.is_finite() && v > 0.0 && v <= MAX_SIZE) {
                return field(name, v, "give a size above 0 and at most 2 m");
            }
        }
        let lengths = [
            ("min_opening", self.min_opening),
            ("pad_from_tip", self.pad_from_tip),
            ("pregrasp", self.pregrasp),
            ("clearance", self.clearance),
            ("wall", self.wall),
        ];
        for (name, v) in lengths {
            if !(v.is_finite() && (0.0..=MAX_SIZE).contains(&v)) {
                return field(name, v, "give a length of 0 to 2 m");
            }
        }
        if self.min_opening >= self.max_opening {
            return field("min_opening", self.min_opening, "must be below max_opening");
        }
        if self.pad_from_tip >= self.finger_depth {
            return field("pad_from_tip", self.pad_from_tip, "must be shorter than finger_depth");
        }
        if !(self.friction.is_finite() && self.friction > 0.0 && self.friction <= 10.0) {
            return field("friction", self.friction, "give a coefficient above 0 and at most 10");
        }
        if !(self.max_tilt.is_finite() && (0.0..=std::f64::consts::PI).contains(&self.max_tilt)) {
            return field("max_tilt", self.max_tilt, "give an angle of 0 to pi rad");
        }
        Ok(())
    }

    /// The half-angle of the friction cone (rad).
    pub fn cone(&self) -> f64 {
        self.friction.atan()
    }
}
