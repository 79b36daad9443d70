//! A sweep recorded as an MCAP file of ROS 2 messages (the `mcap` feature): what Foxglove opens
//! and what `ros2 bag` tools read, beside or instead of the PCD. One file a sweep:
//! - `/sqscan/points` (`sensor_msgs/msg/PointCloud2`): the organized cloud, stamped with the
//!   last profile's time;
//! - `/sqscan/joint_states` (`sensor_msgs/msg/JointState`): the PTU's pan and tilt at each
//!   profile's time;
//! - `/sqscan/detections` (`vision_msgs/msg/Detection3DArray`): the watched objects'
//!   detections on this sweep, at the sweep's time; an empty array where none was found;
//! - a metadata record `sqscan.sweep`: the sweep's id, time, frame, size, viewpoint and the
//!   assembler's report, as the JSON beside it has them.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};

use super::state::{Detected, SweepEntry};
use super::topics;
use crate::atomic::write_atomic;
use crate::model::Model;
use crate::ros::{Time, schema};

/// Writes `path` (atomically, as the PCD and JSON are) for one sweep and the detections made on
/// it.
pub fn write(
    path: &Path,
    entry: &SweepEntry,
    detections: &[(Arc<Model>, Arc<Detected>)],
    frame: &str,
    meta: &serde_json::Value,
) -> Result<()> {
    write_atomic(path, |w| {
        let options = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(concat!("sqscand ", env!("CARGO_PKG_VERSION")));
        let mut out = options.create(&mut *w).context("starting the MCAP file")?;
        let none = BTreeMap::new();
        let mut channel = |name: &str, schema_text: String, topic: &str| -> Result<u16> {
            let s = out.add_schema(name, "ros2msg", schema_text.as_bytes())?;
            Ok(out.add_channel(s, topic, "cdr", &none)?)
        };
        let points = channel(schema::POINT_CLOUD2, schema::point_cloud2(), topics::POINTS)?;
        let joints = channel(schema::JOINT_STATE, schema::joint_state(), topics::JOINTS)?;
        let found = channel(
            schema::DETECTION3D_ARRAY,
            schema::detection3d_array(),
            topics::DETECTIONS,
        )?;
        // The joint states first, in time order, then the cloud and the detections at the end.
        for (i, (stamp, data)) in topics::joint_states(entry).enumerate() {
            out.write_to_known_channel(&message(joints, i as u32, stamp), &data)?;
        }
        let (stamp, data) = topics::cloud(entry, frame);
        out.write_to_known_channel(&message(points, 0, stamp), &data)?;
        let (stamp, data) = topics::detections(entry, detections, frame);
        out.write_to_known_channel(&message(found, 0, stamp), &data)?;
        let mut fields = BTreeMap::new();
        if let Some(m) = meta.as_object() {
            for (k, v) in m {
                fields.insert(
                    k.clone(),
                    v.as_str().map(str::to_string).unwrap_or_else(|| v.to_string()),
                );
            }
        }
        out.write_metadata(&mcap::records::Metadata {
            name: "sqscan.sweep".into(),
            metadata: fields,
        })?;
        out.finish().context("finishing the MCAP file")?;
        Ok(())
    })
}

fn message(channel_id: u16, sequence: u32, stamp: Time) -> mcap::records::MessageHeader {
    mcap::records::MessageHeader {
        channel_id,
        sequence,
        log_time: stamp.nanos(),
        publish_time: stamp.nanos(),
    }
}
