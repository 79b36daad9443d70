//! Poses in files and on the wire.
//!
//! On the wire (JSON) a pose is always `{"position":[x,y,z],"orientation":[qx,qy,qz,qw]}`. In
//! hand-written TOML files the orientation may instead be roll-pitch-yaw (`rpy`, radians, or
//! `rpy_deg`), because nobody types quaternions: rpy follows REP-103 fixed-axis X-Y-Z
//! (roll about x, then pitch about y, then yaw about z).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// The wire form of a pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PoseJson {
    /// Metres, in the reply's frame.
    pub position: [f64; 3],
    /// Unit quaternion `[x, y, z, w]`.
    pub orientation: [f64; 4],
}

impl From<&Isometry3<f64>> for PoseJson {
    fn from(p: &Isometry3<f64>) -> Self {
        let t = p.translation.vector;
        let q = p.rotation.quaternion();
        // One of the two equivalent quaternions, chosen with w >= 0 so output is stable.
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        PoseJson {
            position: [t.x, t.y, t.z],
            orientation: [s * q.i, s * q.j, s * q.k, s * q.w],
        }
    }
}

/// A pose as written in TOML files: a position and at most one orientation form (identity if
/// none is given).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    #[serde(default)]
    pub position: [f64; 3],
    /// Quaternion `[x, y, z, w]`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<[f64; 4]>,
    /// Roll, pitch, yaw in radians.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    /// Roll, pitch, yaw in degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rpy_deg: Option<[f64; 3]>,
}

impl PoseSpec {
    /// Nothing given: the identity.
    pub fn is_identity(&self) -> bool {
        *self == PoseSpec::default()
    }

    /// The pose, or a message saying what is wrong with it.
    pub fn to_isometry(&self) -> Result<Isometry3<f64>, String> {
        if self.position.iter().any(|v| !v.is_finite()) {
            return Err(format!("position {:?} is not finite", self.position));
        }
        let given = [self.orientation.is_some(), self.rpy.is_some(), self.rpy_deg.is_some()];
        if given.iter().filter(|g| **g).count() > 1 {
            return Err("give only one of orientation, rpy, rpy_deg".into());
        }
        let rotation = if let Some(q) = self.orientation {
            quaternion_from_xyzw(q)?
        } else if let Some(r) = self.rpy {
            rpy(r)?
        } else if let Some(r) = self.rpy_deg {
            rpy(r.map(f64::to_radians))?
        } else {
            UnitQuaternion::identity()
        };
        Ok(Isometry3::from_parts(Translation3::from(self.position), rotation))
    }
}

/// A unit quaternion from `[x, y, z, w]`; refuses values that are not close to unit length
/// (a typo, not rounding) rather than silently normalising them.
pub fn quaternion_from_xyzw(q: [f64; 4]) -> Result<UnitQuaternion<f64>, String> {
    let quat = Quaternion::new(q[3], q[0], q[1], q[2]);
    let n = quat.norm();
    if !n.is_finite() || (n - 1.0).abs() > 1e-3 {
        return Err(format!(
            "orientation {q:?} is not a unit quaternion [x, y, z, w] (norm {n})"
        ));
    }
    Ok(UnitQuaternion::from_quaternion(quat))
}

fn rpy(r: [f64; 3]) -> Result<UnitQuaternion<f64>, String> {
    if r.iter().any(|v| !v.is_finite()) {
        return Err(format!("rpy {r:?} is not finite"));
    }
    Ok(UnitQuaternion::from_euler_angles(r[0], r[1], r[2]))
}

/// Rotation error in radians between two orientations (BOP: `arccos((tr(R_a R_b^T) - 1) / 2)`).
pub fn rotation_error(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_and_quaternion_agree() {
        let a = PoseSpec {
            rpy_deg: Some([0.0, 0.0, 90.0]),
            ..Default::default()
        };
        let b = PoseSpec {
            orientation: Some([0.0, 0.0, (0.5f64).sqrt(), (0.5f64).sqrt()]),
            ..Default::default()
        };
        let (a, b) = (a.to_isometry().unwrap(), b.to_isometry().unwrap());
        assert!(rotation_error(&a.rotation, &b.rotation) < 1e-12);
        // Yaw of +90 deg turns x (forward) into y (left), as REP-103 has it.
        let x = a.rotation * nalgebra::Vector3::x();
        assert!((x - nalgebra::Vector3::y()).norm() < 1e-12);
        let j = PoseJson::from(&a);
        assert!(j.orientation[3] > 0.0);
    }

    #[test]
    fn refuses_bad_orientations() {
        let s = PoseSpec {
            orientation: Some([0.0, 0.0, 0.0, 2.0]),
            ..Default::default()
        };
        assert!(s.to_isometry().unwrap_err().contains("unit quaternion"));
        let s = PoseSpec {
            rpy: Some([0.0; 3]),
            rpy_deg: Some([0.0; 3]),
            ..Default::default()
        };
        assert!(s.to_isometry().unwrap_err().contains("only one"));
    }
}
