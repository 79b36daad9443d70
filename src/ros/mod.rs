//! ROS 2 messages, encoded as ROS 2 encodes them (CDR, [`cdr`]), with the message definitions
//! that name their layout (the `ros2msg` schema encoding of MCAP and rosbag2). Written here
//! rather than generated: sqscan needs five message types and no ROS installation, and the
//! encoding is checked against an independent decoder (PyPI `mcap-ros2-support`, in
//! `tests/service/mcap.rs`).
//!
//! The definitions are ROS 2 Humble's and later (`vision_msgs` 4: a `Detection3D` holds its
//! `results`, `bbox` and `id`).

pub mod cdr;
mod display;
pub mod schema;

pub use display::{Marker, Rgba, Shape, image_32fc1, image_data, marker_array};

use crate::model::Model;
use cdr::CdrWriter;
use nalgebra::{Isometry3, Point3, Vector3};

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// From Unix time in seconds (before 1970 or past 2038 it saturates, as ROS's own does).
    pub fn from_unix_s(t: f64) -> Time {
        let t = if t.is_finite() { t.max(0.0) } else { 0.0 };
        let sec = t.floor().min(i32::MAX as f64);
        let nanosec = ((t - sec) * 1e9).round().clamp(0.0, 999_999_999.0) as u32;
        Time {
            sec: sec as i32,
            nanosec,
        }
    }

    /// Nanoseconds since the epoch, as MCAP stamps a message.
    pub fn nanos(self) -> u64 {
        self.sec.max(0) as u64 * 1_000_000_000 + self.nanosec as u64
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Header<'a> {
    pub stamp: Time,
    pub frame_id: &'a str,
}

pub(crate) fn header(w: &mut CdrWriter, h: &Header) {
    w.i32(h.stamp.sec);
    w.u32(h.stamp.nanosec);
    w.string(h.frame_id);
}

fn vector3(w: &mut CdrWriter, v: &Vector3<f64>) {
    w.f64(v.x);
    w.f64(v.y);
    w.f64(v.z);
}

/// `geometry_msgs/Pose`: the position, then the orientation as `x, y, z, w`, of the two
/// equivalent quaternions the one with `w >= 0`, as the JSON replies give it (`PoseJson`).
fn pose(w: &mut CdrWriter, p: &Isometry3<f64>) {
    vector3(w, &p.translation.vector);
    for v in crate::pose::PoseJson::from(p).orientation {
        w.f64(v);
    }
}

/// `sensor_msgs/JointState` with positions only (velocity and effort empty, as the message
/// allows).
pub fn joint_state(h: &Header, names: &[&str], positions: &[f64]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, h);
    w.string_seq(names);
    w.f64_seq(positions);
    w.f64_seq(&[]);
    w.f64_seq(&[]);
    w.finish()
}

/// One `geometry_msgs/TransformStamped`: `child` in `header.frame_id`.
pub struct Transform<'a> {
    pub header: Header<'a>,
    pub child: &'a str,
    pub transform: Isometry3<f64>,
}

/// `tf2_msgs/TFMessage`, as `/tf` and `/tf_static` carry it.
pub fn tf_message(transforms: &[Transform]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.count(transforms.len());
    for t in transforms {
        header(&mut w, &t.header);
        w.string(t.child);
        pose(&mut w, &t.transform);
    }
    w.finish()
}

/// One object found, for a `vision_msgs/Detection3D`.
pub struct Found<'a> {
    /// The object's name (the hypothesis' `class_id`).
    pub object: &'a str,
    /// The detector's confidence in [0, 1] (the hypothesis' `score`).
    pub confidence: f64,
    /// The object's model frame in the header's frame.
    pub pose: Isometry3<f64>,
    /// The model's bounding box in its own frame: centre and size.
    pub bbox: (Point3<f64>, Vector3<f64>),
}

/// `vision_msgs/Detection3DArray`: every detection with the array's header, one hypothesis each
/// (the object, its confidence and its pose; the covariance unknown, all zero), the model's
/// bounding box placed with it, and `id` the object's name with the detection's index
/// (`mug#0`). An empty array says the objects asked for are not there.
pub fn detection3d_array(h: &Header, found: &[Found]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, h);
    w.count(found.len());
    for (k, f) in found.iter().enumerate() {
        header(&mut w, h);
        w.count(1);
        w.string(f.object);
        w.f64(f.confidence);
        pose(&mut w, &f.pose);
        for _ in 0..36 {
            w.f64(0.0);
        }
        let centre = f.pose * Isometry3::translation(f.bbox.0.x, f.bbox.0.y, f.bbox.0.z);
        pose(&mut w, &centre);
        vector3(&mut w, &f.bbox.1);
        w.string(&format!("{}#{k}", f.object));
    }
    w.finish()
}

/// A model's bounding box in its own frame (centre, size): the box around every part's box.
pub fn model_bbox(model: &Model) -> (Point3<f64>, Vector3<f64>) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for part in &model.parts {
        let e = part.shape.local_half_extents();
        for corner in 0..8 {
            let c = Vector3::new(
                if corner & 1 == 0 { -e.x } else { e.x },
                if corner & 2 == 0 { -e.y } else { e.y },
                if corner & 4 == 0 { -e.z } else { e.z },
            );
            let p = part.pose_in_object * Point3::from(c);
            lo = lo.inf(&p.coords);
            hi = hi.sup(&p.coords);
        }
    }
    if !(lo.iter().all(|v| v.is_finite()) && hi.iter().all(|v| v.is_finite())) {
        return (Point3::origin(), Vector3::zeros());
    }
    (Point3::from((lo + hi) / 2.0), hi - lo)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A detection's pose on ROS 2 once went out as the negated quaternion of the same pose in
    /// the JSON reply (both the same rotation; the ros2 test compares them number for number).
    #[test]
    fn a_pose_goes_out_with_the_quaternion_of_the_json_reply() {
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(-0.862, 0.0073, -0.0023, -0.5065));
        let p = Isometry3::from_parts(nalgebra::Translation3::new(0.97, 0.2, 0.77), q);
        let mut w = CdrWriter::new();
        pose(&mut w, &p);
        let bytes = w.finish();
        let mut r = cdr::CdrReader::new(&bytes).unwrap();
        let read: Vec<f64> = (0..7).map(|_| r.f64("pose").unwrap()).collect();
        let json = crate::pose::PoseJson::from(&p);
        assert_eq!(read[..3], json.position);
        assert_eq!(read[3..], json.orientation);
        assert!(read[6] >= 0.0);
    }

    #[test]
    fn time_splits_seconds_and_nanoseconds() {
        assert_eq!(
            Time::from_unix_s(1.25),
            Time {
                sec: 1,
                nanosec: 250_000_000
            }
        );
        assert_eq!(Time::from_unix_s(-5.0), Time::default());
        assert_eq!(Time::from_unix_s(f64::NAN), Time::default());
        assert_eq!(Time::from_unix_s(1e12).sec, i32::MAX);
        assert_eq!(Time::from_unix_s(2.5).nanos(), 2_500_000_000);
    }

    #[test]
    fn every_schema_names_each_type_it_uses_once() {
        for s in [
            schema::point_cloud2(),
            schema::joint_state(),
            schema::tf_message(),
            schema::detection3d_array(),
        ] {
            let defined: Vec<&str> = s.lines().filter_map(|l| l.strip_prefix("MSG: ")).collect();
            let mut unique = defined.clone();
            unique.sort();
            unique.dedup();
            assert_eq!(unique.len(), defined.len(), "{s}");
            for l in s.lines() {
                let ty = l.split_whitespace().next().unwrap_or("").trim_end_matches("[]");
                let ty = ty.split('[').next().unwrap_or("");
                if ty.contains('/') {
                    assert!(defined.contains(&ty), "{ty} is not defined in\n{s}");
                }
            }
        }
    }

    #[test]
    fn a_models_box_holds_every_part() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let m = Model::load("mallet", &dir).unwrap();
        let (c, size) = model_bbox(&m);
        // The head 6 cm across at the origin, the shaft 24 cm long along x from 5 to 29 cm.
        assert!((size.x - 0.32).abs() < 1e-9, "{size}");
        assert!((c.x - 0.13).abs() < 1e-9, "{c}");
        assert!((size.z - 0.112).abs() < 1e-9, "{size}");
    }
}
