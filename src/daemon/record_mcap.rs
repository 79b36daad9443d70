//! A sweep recorded as an MCAP file of ROS 2 messages (the `mcap` feature): what Foxglove opens
//! and what `ros2 bag` tools read, beside or instead of the PCD. One file a sweep:
//! - `/sqscan/points` (`sensor_msgs/msg/PointCloud2`): the organized cloud, stamped with the
//!   last profile's time;
//! - `/sqscan/joint_states` (`sensor_msgs/msg/JointState`): the PTU's pan and tilt at each
//!   profile's time;
//! - `/sqscan/range` (`sensor_msgs/msg/Image`): its range image;
//! - `/tf` (`tf2_msgs/msg/TFMessage`): the pan and tilt joints as transforms at each profile's
//!   time, and `/tf_static` the rig's mount, where the backend knows it (not a replay);
//! - `/sqscan/detections` (`vision_msgs/msg/Detection3DArray`): the watched objects'
//!   detections on this sweep, at the sweep's time; an empty array where none was found;
//! - `/sqscan/markers` (`visualization_msgs/msg/MarkerArray`): their fitted parts and the
//!   support plane, drawn;
//! - a metadata record `sqscan.sweep`: the sweep's id, time, frame, size, viewpoint and the
//!   assembler's report, as the JSON beside it has them.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};

use super::backend::Mount;
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
    mount: Option<&Mount>,
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
        let range = channel(schema::IMAGE, schema::image(), topics::RANGE)?;
        let tf = channel(schema::TF_MESSAGE, schema::tf_message(), "/tf")?;
        let drawn = channel(schema::MARKER_ARRAY, schema::marker_array(), topics::MARKERS)?;
        if let Some(m) = mount {
            let tf_static = channel(schema::TF_MESSAGE, schema::tf_message(), "/tf_static")?;
            // Stamped with the first profile's time: every message of the file finds it.
            let first = topics::first_profile_time(entry);
            out.write_to_known_channel(&message(tf_static, 0, first), &topics::tf_static(frame, m, first))?;
        }
        for (i, (stamp, data)) in topics::joint_states(entry).enumerate() {
            out.write_to_known_channel(&message(joints, i as u32, stamp), &data)?;
        }
        for (i, (stamp, data)) in topics::tf_joints(entry).enumerate() {
            out.write_to_known_channel(&message(tf, i as u32, stamp), &data)?;
        }
        let (stamp, data) = topics::cloud(entry, frame);
        out.write_to_known_channel(&message(points, 0, stamp), &data)?;
        let (stamp, data) = topics::range_image(entry);
        out.write_to_known_channel(&message(range, 0, stamp), &data)?;
        let (stamp, data) = topics::detections(entry, detections, frame);
        out.write_to_known_channel(&message(found, 0, stamp), &data)?;
        let (stamp, data) = topics::markers(entry, detections, frame);
        out.write_to_known_channel(&message(drawn, 0, stamp), &data)?;
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
