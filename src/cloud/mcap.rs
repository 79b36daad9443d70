//! The first `sensor_msgs/msg/PointCloud2` of an MCAP file as a cloud (the `mcap` feature): the
//! daemon's own MCAP recordings (`/sqscan/points`, with the viewpoint from their `sqscan.sweep`
//! metadata), and any other uncompressed MCAP file with a ROS 2 cloud in CDR (a `ros2 bag` in
//! MCAP storage without compression: the cloud on the first topic that has one, without a
//! viewpoint). The records are read here, each length checked against the bytes present: a
//! corrupt file from elsewhere is an error naming what is wrong.

use std::collections::HashMap;

use super::{CloudError, PointCloud};
use crate::ros::schema;

/// The topic sqscand records its clouds on.
const POINTS_TOPIC: &str = "/sqscan/points";

/// Bytes read off a record's content, each read checked against what is there. (The MCAP
/// crate's own reader is not used for files from elsewhere: it panics on some corrupt ones.)
struct Bytes<'a> {
    b: &'a [u8],
    what: &'static str,
}

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if n > self.b.len() {
            return Err(format!("{} record cut short", self.what));
        }
        let (head, rest) = self.b.split_at(n);
        self.b = rest;
        Ok(head)
    }
    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2)?.try_into().unwrap_or_default()))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap_or_default()))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap_or_default()))
    }
    fn string(&mut self) -> Result<&'a str, String> {
        let n = self.u32()? as usize;
        std::str::from_utf8(self.take(n)?).map_err(|_| format!("{} record: a string not UTF-8", self.what))
    }
    fn map(&mut self) -> Result<Vec<(&'a str, &'a str)>, String> {
        let n = self.u32()? as usize;
        let mut inner = Bytes {
            b: self.take(n)?,
            what: self.what,
        };
        let mut out = Vec::new();
        while !inner.b.is_empty() {
            out.push((inner.string()?, inner.string()?));
        }
        Ok(out)
    }
}

/// What a pass over the records keeps.
#[derive(Default)]
struct Found<'a> {
    /// Schema id: its name and encoding.
    schemas: HashMap<u16, (&'a str, &'a str)>,
    /// Channel id: its topic, schema id and message encoding.
    channels: HashMap<u16, (&'a str, u16, &'a str)>,
    viewpoint: Option<[f64; 7]>,
    /// The sweep's id and time (Unix s) in sqscand's `sqscan.sweep` metadata.
    sweep: Option<(u64, f64)>,
    /// The first PointCloud2 (topic, message), replaced by the first on [`POINTS_TOPIC`].
    cloud: Option<(&'a str, &'a [u8])>,
}

impl<'a> Found<'a> {
    /// A message record: kept where it is the best PointCloud2 so far.
    fn message(&mut self, content: &'a [u8]) -> Result<(), String> {
        let mut r = Bytes {
            b: content,
            what: "message",
        };
        let channel = r.u16()?;
        r.take(4 + 8 + 8)?;
        let Some(&(topic, schema_id, encoding)) = self.channels.get(&channel) else {
            return Err(format!(
                "a message on channel {channel}, which no channel record defined"
            ));
        };
        let is_cloud = self
            .schemas
            .get(&schema_id)
            .is_some_and(|s| s.0 == schema::POINT_CLOUD2);
        let better = self
            .cloud
            .is_none_or(|(t, _)| t != POINTS_TOPIC && topic == POINTS_TOPIC);
        if is_cloud && encoding == "cdr" && better {
            self.cloud = Some((topic, r.b));
        }
        Ok(())
    }

    /// A metadata record: sqscand's `sqscan.sweep` gives the viewpoint, the sweep's id and time.
    fn metadata(&mut self, content: &'a [u8]) -> Result<(), String> {
        let mut r = Bytes {
            b: content,
            what: "metadata",
        };
        if r.string()? == "sqscan.sweep" {
            let fields = r.map()?;
            let field = |key: &str| fields.iter().find(|(k, _)| *k == key).map(|(_, v)| *v);
            if let Some(v) = field("viewpoint") {
                self.viewpoint =
                    serde_json::from_str(v).map_err(|e| format!("metadata sqscan.sweep: viewpoint {v:?}: {e}"))?;
            }
            let id = field("id").and_then(|v| v.parse::<u64>().ok());
            let time = field("time")
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|t| t.is_finite());
            self.sweep = id.zip(time);
        }
        Ok(())
    }
}

/// The records of `b` (a file's data section, or an uncompressed chunk's records), in order,
/// until the data section ends.
fn records<'a>(mut b: &'a [u8], found: &mut Found<'a>, depth: u32) -> Result<(), String> {
    while !b.is_empty() {
        if b.len() < 9 {
            return Err(format!("{} bytes left where a record begins", b.len()));
        }
        let op = b[0];
        let len = u64::from_le_bytes(b[1..9].try_into().unwrap_or_default());
        let len = usize::try_from(len).ok().filter(|&l| l <= b.len() - 9).ok_or_else(|| {
            format!(
                "a record (opcode {op:#04x}) of {len} bytes, {} left in the file",
                b.len() - 9
            )
        })?;
        let content = &b[9..9 + len];
        b = &b[9 + len..];
        match op {
            // Footer, DataEnd: the data section ends; the summary after it repeats what was read.
            0x02 | 0x0f => return Ok(()),
            0x03 => {
                let mut r = Bytes {
                    b: content,
                    what: "schema",
                };
                let id = r.u16()?;
                let (name, encoding) = (r.string()?, r.string()?);
                found.schemas.insert(id, (name, encoding));
            }
            0x04 => {
                let mut r = Bytes {
                    b: content,
                    what: "channel",
                };
                let id = r.u16()?;
                let schema_id = r.u16()?;
                let (topic, encoding) = (r.string()?, r.string()?);
                found.channels.insert(id, (topic, schema_id, encoding));
            }
            0x05 => found.message(content)?,
            0x06 if depth == 0 => {
                let mut r = Bytes {
                    b: content,
                    what: "chunk",
                };
                r.take(8 + 8 + 8 + 4)?;
                let compression = r.string()?;
                let n = r.u64()?;
                let inner = r.take(usize::try_from(n).unwrap_or(usize::MAX))?;
                if !compression.is_empty() {
                    return Err(format!(
                        "a chunk compressed with {compression:?}: only uncompressed MCAP is read (sqscand writes it so)"
                    ));
                }
                records(inner, found, 1)?;
            }
            0x0c => found.metadata(content)?,
            _ => {}
        }
    }
    Ok(())
}

/// One pass over an MCAP file's records: what [`records`] keeps.
fn scan(bytes: &[u8]) -> Result<Found<'_>, CloudError> {
    let data = bytes
        .strip_prefix(super::codec::MCAP_MAGIC)
        .ok_or_else(|| bad("no MCAP magic at the start".into()))?;
    let mut found = Found::default();
    records(data, &mut found, 0).map_err(bad)?;
    Ok(found)
}

fn bad(msg: String) -> CloudError {
    CloudError::Format(format!("MCAP: {msg}"))
}

/// The sweep id and time (Unix s) of sqscand's own MCAP recording, from its `sqscan.sweep`
/// metadata; `None` for a file without them (one from elsewhere).
pub fn recorded_sweep(bytes: &[u8]) -> Result<Option<(u64, f64)>, CloudError> {
    Ok(scan(bytes)?.sweep)
}

pub fn parse_mcap(bytes: &[u8]) -> Result<PointCloud, CloudError> {
    let found = scan(bytes)?;
    let Some((topic, message)) = found.cloud else {
        return Err(bad(format!("no {} message in CDR", schema::POINT_CLOUD2)));
    };
    let mut cloud = super::read_point_cloud2(message).map_err(|e| bad(format!("{topic}: {e}")))?;
    super::check_point_count(cloud.points.len()).map_err(|msg| bad(format!("{topic}: {msg}")))?;
    cloud.viewpoint = found.viewpoint;
    Ok(cloud)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::{Header, Time};

    /// An MCAP file of one PointCloud2 on `topic`, with or without the daemon's metadata.
    fn file(topic: &str, viewpoint: Option<&str>) -> (PointCloud, Vec<u8>) {
        let mut cloud = PointCloud::from_points((0..40).map(|i| [i as f32, 0.5, f32::NAN]).collect());
        cloud.width = 8;
        cloud.height = 5;
        let msg = crate::cloud::point_cloud2(
            &cloud,
            &Header {
                stamp: Time::default(),
                frame_id: "base_link",
            },
        );
        let mut out = std::io::Cursor::new(Vec::new());
        let mut w = mcap::WriteOptions::new().compression(None).create(&mut out).unwrap();
        let s = w
            .add_schema(schema::POINT_CLOUD2, "ros2msg", schema::point_cloud2().as_bytes())
            .unwrap();
        let c = w.add_channel(s, topic, "cdr", &Default::default()).unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: c,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        w.write_to_known_channel(&header, &msg).unwrap();
        if let Some(v) = viewpoint {
            w.write_metadata(&mcap::records::Metadata {
                name: "sqscan.sweep".into(),
                metadata: [("viewpoint".to_string(), v.to_string())].into(),
            })
            .unwrap();
        }
        w.finish().unwrap();
        drop(w);
        (cloud, out.into_inner())
    }

    #[test]
    fn the_cloud_and_its_viewpoint_read_back() {
        let (cloud, bytes) = file("/sqscan/points", Some("[1,2,3,1,0,0,0]"));
        let back = parse_mcap(&bytes).unwrap();
        assert_eq!((back.width, back.height), (8, 5));
        assert_eq!(back.viewpoint, Some([1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0]));
        assert_eq!(back.points[7][0], cloud.points[7][0]);
        // Another recorder's cloud, on its own topic and without our metadata.
        let back = parse_mcap(&file("/camera/points", None).1).unwrap();
        assert_eq!(back.viewpoint, None);
        let e = parse_mcap(&file("/x", Some("[1,2]")).1).unwrap_err().to_string();
        assert!(e.contains("viewpoint"), "{e}");
    }

    /// Regression: through the MCAP crate's reader, a cut file made the metadata scan spin
    /// forever on the reader's repeated error, and a flipped byte in a chunk made the reader
    /// panic (a length past the chunk's end). Cut anywhere or with any byte flipped, a file is an
    /// answer or an error.
    #[test]
    fn a_cut_or_corrupt_mcap_file_is_an_error_not_a_hang() {
        let (_, bytes) = file("/sqscan/points", Some("[1,2,3,1,0,0,0]"));
        for cut in 0..bytes.len() {
            let _ = parse_mcap(&bytes[..cut]);
        }
        for i in 8..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0xa5;
            let _ = parse_mcap(&b);
        }
    }
}
