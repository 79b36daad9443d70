//! ROS 2 messages, encoded as ROS 2 encodes them (CDR, [`cdr`]), with the message definitions
//! that name their layout (the `ros2msg` schema encoding of MCAP and rosbag2). Written here
//! rather than generated: sqscan needs five message types and no ROS installation, and the
//! encoding is checked against an independent decoder (PyPI `mcap-ros2-support`, in
//! `tests/mcap.rs`).
//!
//! The definitions are ROS 2 Humble's and later (`vision_msgs` 4: a `Detection3D` holds its
//! `results`, `bbox` and `id`).

pub mod cdr;
mod display;
pub mod schema;

pub use display::{Marker, Rgba, Shape, image_32fc1, image_data, marker_array};

use crate::cloud::{FieldData, PointCloud};
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

fn header(w: &mut CdrWriter, h: &Header) {
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

/// `sensor_msgs/PointField` data types.
fn datatype(d: &FieldData) -> (u8, usize) {
    match d {
        FieldData::I8(_) => (1, 1),
        FieldData::U8(_) => (2, 1),
        FieldData::I16(_) => (3, 2),
        FieldData::U16(_) => (4, 2),
        FieldData::I32(_) => (5, 4),
        FieldData::U32(_) => (6, 4),
        FieldData::F32(_) => (7, 4),
        FieldData::F64(_) => (8, 8),
    }
}

/// The little-endian bytes of value `i` of a field.
fn value_bytes(d: &FieldData, i: usize, out: &mut [u8]) {
    match d {
        FieldData::I8(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::U8(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::I16(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::U16(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::I32(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::U32(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::F32(v) => out.copy_from_slice(&v[i].to_le_bytes()),
        FieldData::F64(v) => out.copy_from_slice(&v[i].to_le_bytes()),
    }
}

/// `sensor_msgs/PointCloud2` of a cloud, organized as it is (`height` rows of `width`; a
/// sweep's rows are its profiles), points without a return kept as NaN and `is_dense` false.
/// The fields are `x`, `y`, `z` (float32) and then the cloud's own scalar fields (a sweep's
/// `intensity`, a simulated sweep's `label`), each aligned to its size.
pub fn point_cloud2(cloud: &PointCloud, h: &Header) -> Vec<u8> {
    let mut fields: Vec<(&str, usize, u8, Option<&FieldData>)> =
        vec![("x", 0, 7, None), ("y", 4, 7, None), ("z", 8, 7, None)];
    let mut step: usize = 12;
    let mut align: usize = 4;
    for f in cloud
        .fields
        .iter()
        .filter(|f| f.count == 1 && f.data.len() == cloud.points.len())
    {
        let (ty, size) = datatype(&f.data);
        step = step.next_multiple_of(size);
        fields.push((f.name.as_str(), step, ty, Some(&f.data)));
        step += size;
        align = align.max(size);
    }
    let step = step.next_multiple_of(align);
    let n = cloud.points.len();
    let mut data = vec![0u8; n * step];
    for (i, (p, row)) in cloud.points.iter().zip(data.chunks_exact_mut(step)).enumerate() {
        for k in 0..3 {
            row[4 * k..4 * k + 4].copy_from_slice(&p[k].to_le_bytes());
        }
        for &(_, offset, ty, d) in &fields[3..] {
            let size = datatype_size(ty);
            if let Some(d) = d {
                value_bytes(d, i, &mut row[offset..offset + size]);
            }
        }
    }
    let (width, height) = if cloud.width * cloud.height == n {
        (cloud.width, cloud.height)
    } else {
        (n, 1)
    };
    let mut w = CdrWriter::with_capacity(data.len() + 256);
    header(&mut w, h);
    w.count(height);
    w.count(width);
    w.count(fields.len());
    for (name, offset, ty, _) in &fields {
        w.string(name);
        w.count(*offset);
        w.u8(*ty);
        w.u32(1);
    }
    w.bool(false);
    w.count(step);
    w.count(step * width);
    w.bytes(&data);
    w.bool(false);
    w.finish()
}

/// A `PointCloud2` up to its `data`, and the `is_dense` after it.
struct Head<'a> {
    height: usize,
    width: usize,
    /// Name, offset, datatype, count.
    fields: Vec<(&'a str, usize, u8, usize)>,
    step: usize,
    data: &'a [u8],
}

fn head(msg: &[u8]) -> Result<Head<'_>, String> {
    let mut r = cdr::CdrReader::new(msg)?;
    r.i32("header.stamp.sec")?;
    r.u32("header.stamp.nanosec")?;
    r.string("header.frame_id")?;
    let height = r.u32("height")? as usize;
    let width = r.u32("width")? as usize;
    let n_fields = r.u32("fields")? as usize;
    let mut fields = Vec::new();
    for k in 0..n_fields.min(msg.len() / 16) {
        let name = r.string(&format!("fields[{k}].name"))?;
        let offset = r.u32(&format!("fields[{k}].offset"))? as usize;
        let ty = r.u8(&format!("fields[{k}].datatype"))?;
        let count = r.u32(&format!("fields[{k}].count"))? as usize;
        fields.push((name, offset, ty, count));
    }
    if fields.len() < n_fields {
        return Err(format!("{n_fields} fields in a message of {} bytes", msg.len()));
    }
    if r.bool("is_bigendian")? {
        return Err("is_bigendian: big-endian points are not read".into());
    }
    let step = r.u32("point_step")? as usize;
    r.u32("row_step")?;
    let data = r.bytes("data")?;
    r.bool("is_dense")?;
    Ok(Head {
        height,
        width,
        fields,
        step,
        data,
    })
}

/// Where a `PointCloud2`'s `data` lies in the message (after its length), `None` where the
/// message is not one.
pub fn point_cloud2_data(msg: &[u8]) -> Option<std::ops::Range<usize>> {
    let data = head(msg).ok()?.data;
    let start = data.as_ptr() as usize - msg.as_ptr() as usize;
    Some(start..start + data.len())
}

/// A `sensor_msgs/PointCloud2` as a cloud: `x`, `y`, `z` (float32 or float64) as the points,
/// every other scalar field kept with its type, `height x width` kept. Errors name the field that
/// is wrong; sizes are checked against the bytes present before anything is allocated.
pub fn read_point_cloud2(msg: &[u8]) -> Result<PointCloud, String> {
    let Head {
        height,
        width,
        fields,
        step,
        data,
    } = head(msg)?;
    let n = height
        .checked_mul(width)
        .filter(|&n| n.checked_mul(step) == Some(data.len()))
        .ok_or_else(|| {
            format!(
                "height {height} x width {width} x point_step {step} is not the {} bytes of data",
                data.len()
            )
        })?;
    let mut points = vec![[f32::NAN; 3]; n];
    let mut extra = Vec::new();
    for &(name, offset, ty, count) in &fields {
        if !(1..=8).contains(&ty) {
            return Err(format!("field `{name}`: datatype {ty} is none of PointField's 1 to 8"));
        }
        let size = datatype_size(ty);
        if count != 1 || offset.checked_add(size).is_none_or(|end| end > step) {
            return Err(format!(
                "field `{name}`: {count} values of {size} bytes at offset {offset} do not fit a point of {step} bytes"
            ));
        }
        let value = |i: usize| &data[i * step + offset..i * step + offset + size];
        let axis = ["x", "y", "z"].iter().position(|a| *a == name);
        match (axis, ty) {
            (Some(k), 7) => {
                (0..n).for_each(|i| points[i][k] = f32::from_le_bytes(value(i).try_into().unwrap_or([0; 4])))
            }
            (Some(k), 8) => {
                (0..n).for_each(|i| points[i][k] = f64::from_le_bytes(value(i).try_into().unwrap_or([0; 8])) as f32)
            }
            (Some(_), _) => return Err(format!("field `{name}`: a coordinate must be float32 or float64")),
            (None, _) => {
                let le = |i: usize| value(i);
                let d = match ty {
                    1 => FieldData::I8((0..n).map(|i| le(i)[0] as i8).collect()),
                    2 => FieldData::U8((0..n).map(|i| le(i)[0]).collect()),
                    3 => FieldData::I16((0..n).map(|i| i16::from_le_bytes([le(i)[0], le(i)[1]])).collect()),
                    4 => FieldData::U16((0..n).map(|i| u16::from_le_bytes([le(i)[0], le(i)[1]])).collect()),
                    5 => FieldData::I32(
                        (0..n)
                            .map(|i| i32::from_le_bytes(le(i).try_into().unwrap_or([0; 4])))
                            .collect(),
                    ),
                    6 => FieldData::U32(
                        (0..n)
                            .map(|i| u32::from_le_bytes(le(i).try_into().unwrap_or([0; 4])))
                            .collect(),
                    ),
                    7 => FieldData::F32(
                        (0..n)
                            .map(|i| f32::from_le_bytes(le(i).try_into().unwrap_or([0; 4])))
                            .collect(),
                    ),
                    _ => FieldData::F64(
                        (0..n)
                            .map(|i| f64::from_le_bytes(le(i).try_into().unwrap_or([0; 8])))
                            .collect(),
                    ),
                };
                extra.push(crate::cloud::Field::scalar(name, d));
            }
        }
    }
    for a in ["x", "y", "z"] {
        if !fields.iter().any(|f| f.0 == a) {
            return Err(format!("no field `{a}`"));
        }
    }
    let mut cloud = PointCloud::from_points(points);
    cloud.width = width;
    cloud.height = height;
    cloud.fields = extra;
    Ok(cloud)
}

fn datatype_size(ty: u8) -> usize {
    match ty {
        1 | 2 => 1,
        3 | 4 => 2,
        8 => 8,
        _ => 4,
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
    use crate::cloud::Field;

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

    /// Two points of an organized 2 x 1 cloud with an intensity: the fields' offsets, the step
    /// and the points' bytes where the layout puts them.
    #[test]
    fn a_point_cloud2_lays_out_its_fields() {
        let mut cloud = PointCloud::from_points(vec![[1.0, 2.0, 3.0], [f32::NAN; 3]]);
        cloud.width = 1;
        cloud.height = 2;
        cloud.fields.push(Field::scalar("intensity", FieldData::U8(vec![7, 0])));
        cloud.fields.push(Field::scalar("label", FieldData::U32(vec![3, 4])));
        let b = point_cloud2(
            &cloud,
            &Header {
                stamp: Time { sec: 1, nanosec: 2 },
                frame_id: "base_link",
            },
        );
        // x y z at 0 4 8, intensity at 12, label at 16: 20 bytes a point.
        let data_len = 40u32.to_le_bytes();
        let at = b.windows(4).rposition(|w| w == data_len).expect("the data's length");
        let data = &b[at + 4..at + 44];
        assert_eq!(&data[0..4], &1.0f32.to_le_bytes());
        assert_eq!(&data[8..12], &3.0f32.to_le_bytes());
        assert_eq!(data[12], 7);
        assert_eq!(&data[16..20], &3u32.to_le_bytes());
        assert!(f32::from_le_bytes(data[20..24].try_into().unwrap()).is_nan());
        assert_eq!(&data[36..40], &4u32.to_le_bytes());
        assert_eq!(b.last(), Some(&0), "is_dense false");
        // height 2, width 1 right after the header.
        let h = 4 + 8 + 4 + "base_link\0".len();
        let h = h.next_multiple_of(4);
        assert_eq!(&b[h..h + 8], &[2, 0, 0, 0, 1, 0, 0, 0]);
    }

    /// A cloud through PointCloud2 and back: the same points to the bit (NaN kept), the same
    /// organization and fields; every message cut short is an error, not a panic.
    #[test]
    fn a_point_cloud2_reads_back_as_the_cloud_it_was() {
        let mut cloud = PointCloud::from_points(vec![[1.0, -2.0, 3.5], [f32::NAN; 3], [0.25, 0.5, 0.75]]);
        cloud.width = 3;
        cloud.height = 1;
        cloud
            .fields
            .push(Field::scalar("intensity", FieldData::U8(vec![7, 0, 9])));
        cloud
            .fields
            .push(Field::scalar("range", FieldData::F64(vec![1.0, f64::NAN, 2.0])));
        let h = Header {
            stamp: Time::default(),
            frame_id: "base_link",
        };
        let msg = point_cloud2(&cloud, &h);
        let back = read_point_cloud2(&msg).unwrap();
        assert_eq!((back.width, back.height), (3, 1));
        let bits = |c: &PointCloud| c.points.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&cloud));
        assert_eq!(back.fields.len(), 2);
        assert!(matches!(&back.fields[0].data, FieldData::U8(v) if v == &[7, 0, 9]));
        for cut in 0..msg.len() {
            assert!(read_point_cloud2(&msg[..cut]).is_err(), "cut at {cut}");
        }
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
