//! The messages that draw what a sweep and a detection are: a range image
//! (`sensor_msgs/Image`) and markers (`visualization_msgs/MarkerArray`).

use nalgebra::{Isometry3, Point3, Vector3};

use super::cdr::{self, CdrWriter};
use super::{Header, header, pose, vector3};

/// `sensor_msgs/Image` of one float32 channel (`32FC1`), row-major, little-endian: a sweep's
/// range image (a row a profile, m, NaN for no return).
pub fn image_32fc1(h: &Header, height: usize, width: usize, values: &[f32]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(4 * values.len() + 128);
    header(&mut w, h);
    w.count(height);
    w.count(width);
    w.string("32FC1");
    w.u8(0);
    w.count(4 * width);
    let mut data = Vec::with_capacity(4 * values.len());
    for v in values {
        data.extend_from_slice(&v.to_le_bytes());
    }
    w.bytes(&data);
    w.finish()
}

/// Where an `Image`'s `data` lies in the message (after its length): the message ends with it.
/// `None` where the message is not one.
pub fn image_data(msg: &[u8]) -> Option<std::ops::Range<usize>> {
    let mut r = cdr::CdrReader::new(msg).ok()?;
    r.i32("header.stamp.sec").ok()?;
    r.u32("header.stamp.nanosec").ok()?;
    r.string("header.frame_id").ok()?;
    r.u32("height").ok()?;
    r.u32("width").ok()?;
    r.string("encoding").ok()?;
    r.u8("is_bigendian").ok()?;
    r.u32("step").ok()?;
    let data = r.bytes("data").ok()?;
    let start = data.as_ptr() as usize - msg.as_ptr() as usize;
    (start + data.len() == msg.len()).then_some(start..msg.len())
}

/// An RGBA colour, each component 0 to 1 (`std_msgs/ColorRGBA`).
pub type Rgba = [f32; 4];

/// What a `visualization_msgs/Marker` draws.
pub enum Shape<'a> {
    /// `POINTS` at the given positions (in the header's frame), `size` (m) across.
    Points { points: &'a [Point3<f64>], size: f64 },
    /// A `CUBE` of the given size at the pose.
    Cube { pose: Isometry3<f64>, size: Vector3<f64> },
    /// `DELETEALL`: clears what was drawn before.
    DeleteAll,
}

/// One `visualization_msgs/Marker` (ROS 2 Humble's definition).
pub struct Marker<'a> {
    pub ns: &'a str,
    pub id: i32,
    pub shape: Shape<'a>,
    pub color: Rgba,
}

/// `visualization_msgs/MarkerArray`, every marker with the header `h`, lasting until replaced.
pub fn marker_array(h: &Header, markers: &[Marker]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.count(markers.len());
    for m in markers {
        header(&mut w, h);
        w.string(m.ns);
        w.i32(m.id);
        let (kind, action, pose_of, scale, points): (i32, i32, Isometry3<f64>, Vector3<f64>, &[Point3<f64>]) = match &m
            .shape
        {
            Shape::Points { points, size } => (8, 0, Isometry3::identity(), Vector3::new(*size, *size, 0.0), points),
            Shape::Cube { pose, size } => (1, 0, *pose, *size, &[]),
            Shape::DeleteAll => (0, 3, Isometry3::identity(), Vector3::zeros(), &[]),
        };
        w.i32(kind);
        w.i32(action);
        pose(&mut w, &pose_of);
        vector3(&mut w, &scale);
        for c in m.color {
            w.f32(c);
        }
        // lifetime 0: until replaced; frame_locked false.
        w.i32(0);
        w.u32(0);
        w.bool(false);
        w.count(points.len());
        for p in points {
            vector3(&mut w, &p.coords);
        }
        w.count(0); // colors
        w.string(""); // texture_resource
        header(&mut w, &Header::default()); // texture: a CompressedImage, empty
        w.string("");
        w.bytes(&[]);
        w.count(0); // uv_coordinates
        w.string(""); // text
        w.string(""); // mesh_resource
        w.string(""); // mesh_file: filename, data
        w.bytes(&[]);
        w.bool(false); // mesh_use_embedded_materials
    }
    w.finish()
}
