//! `sensor_msgs/PointCloud2`, the ROS 2 message of a point cloud, as a cloud format: a cloud
//! written as one (organized as it is, NaN kept) and one read back as a cloud, for the live
//! topics, the recordings and the MCAP files `read_cloud` opens.

use super::{Field, FieldData, PointCloud};
use crate::ros::cdr::{self, CdrWriter};
use crate::ros::{Header, header};

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
                extra.push(Field::scalar(name, d));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::Time;

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
}
