//! A sweep recorded as an MCAP file of ROS 2 messages (the `mcap` feature): what Foxglove opens
//! and what `ros2 bag` tools read, beside or instead of the PCD, one of the storage files of the
//! recording directory's rosbag2 bag ([`super::bag`]). One file a sweep, its messages in
//! log-time order, each channel with the `offered_qos_profiles` rosbag2 records:
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
use super::bag::{self, FileStats};
use super::state::{Detected, SweepEntry};
use super::topics;
use crate::atomic::write_atomic;
use crate::model::Model;
use crate::ros::Time;

/// Writes `path` (atomically, as the PCD and JSON are) for one sweep and the detections made on
/// it; returns what it holds, for the bag's metadata.
pub fn write(
    path: &Path,
    entry: &SweepEntry,
    detections: &[(Arc<Model>, Arc<Detected>)],
    mount: Option<&Mount>,
    frame: &str,
    meta: &serde_json::Value,
) -> Result<FileStats> {
    let mut stats = FileStats::default();
    write_atomic(path, |w| {
        let options = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(concat!("sqscand ", env!("CARGO_PKG_VERSION")));
        let mut out = options.create(&mut *w).context("starting the MCAP file")?;
        let mut channels: BTreeMap<&str, u16> = BTreeMap::new();
        let mut topics_used = vec![
            topics::JOINTS,
            "/tf",
            topics::POINTS,
            topics::RANGE,
            topics::DETECTIONS,
            topics::MARKERS,
        ];
        if mount.is_some() {
            topics_used.insert(0, "/tf_static");
        }
        for topic in topics_used {
            let (name, definition) = bag::topic_type(topic).context("a recorded topic without a type")?;
            let s = out.add_schema(name, "ros2msg", definition().as_bytes())?;
            // As rosbag2 records a topic: with the QoS it was offered at.
            let qos = BTreeMap::from([("offered_qos_profiles".to_string(), bag::offered_qos(topic))]);
            channels.insert(topic, out.add_channel(s, topic, "cdr", &qos)?);
        }
        let mut sequence: BTreeMap<&str, u32> = BTreeMap::new();
        // In log-time order, as a bag's messages are: the mount at the first profile's time, each
        // profile's joint state and transforms, then the cloud and the rest at the last's.
        let mut put = |topic: &'static str, stamp: Time, data: &[u8]| -> Result<()> {
            let n = sequence.entry(topic).or_default();
            out.write_to_known_channel(&message(channels[topic], *n, stamp), data)?;
            *n += 1;
            stats.count(topic, stamp.nanos());
            Ok(())
        };
        if let Some(m) = mount {
            // Stamped with the first profile's time: every message of the file finds it.
            let first = topics::first_profile_time(entry);
            put("/tf_static", first, &topics::tf_static(frame, m, first))?;
        }
        for ((stamp, joint), (_, tf)) in topics::joint_states(entry).zip(topics::tf_joints(entry)) {
            put(topics::JOINTS, stamp, &joint)?;
            put("/tf", stamp, &tf)?;
        }
        let (stamp, data) = topics::cloud(entry, frame);
        put(topics::POINTS, stamp, &data)?;
        let (stamp, data) = topics::range_image(entry);
        put(topics::RANGE, stamp, &data)?;
        let (stamp, data) = topics::detections(entry, detections, frame);
        put(topics::DETECTIONS, stamp, &data)?;
        let (stamp, data) = topics::markers(entry, detections, frame);
        put(topics::MARKERS, stamp, &data)?;
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
    })?;
    Ok(stats)
}

fn message(channel_id: u16, sequence: u32, stamp: Time) -> mcap::records::MessageHeader {
    mcap::records::MessageHeader {
        channel_id,
        sequence,
        log_time: stamp.nanos(),
        publish_time: stamp.nanos(),
    }
}
