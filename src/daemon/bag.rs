//! A recording directory as a rosbag2 bag (the `mcap` feature): the sweeps' MCAP files are its
//! storage files, and `metadata.yaml` beside them says so as rosbag2 writes it in ROS 2 Humble
//! (format version 5, storage `mcap`), so that rosbag2's tools and readers such as PyPI's
//! `rosbags` open the directory as one bag of every recorded sweep.
//!
//! Each topic's channel carries `offered_qos_profiles` as rosbag2 records them: the QoS that
//! sqscand's ROS 2 node offers at its defaults (`docs/ROS2.md`), so that a bag player publishes
//! `/tf_static` transient local, as tf2 expects. The metadata is rewritten after every recorded
//! sweep and every prune, from the sweeps' JSON files (each counts its MCAP file's messages), so
//! it lists exactly the MCAP files on disk.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Mutex;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::config::Ros2Config;
use super::topics;
use crate::atomic::write_atomic;
use crate::ros::schema;

/// The bag's metadata file, as rosbag2 names it.
pub const METADATA: &str = "metadata.yaml";

/// rosbag2's metadata format version of ROS 2 Humble (Iron writes 6 and later 8 and 9; their
/// readers read 5).
const VERSION: u32 = 5;

/// What one MCAP file holds, as its sweep's JSON keeps it (`"bag"`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FileStats {
    /// Log time of its first and last message (ns since the Unix epoch).
    pub start_ns: u64,
    pub end_ns: u64,
    /// Messages by topic.
    pub messages: BTreeMap<String, u64>,
}

impl FileStats {
    /// Counts a message on `topic` logged at `ns`.
    pub fn count(&mut self, topic: &str, ns: u64) {
        if self.messages.is_empty() {
            self.start_ns = ns;
            self.end_ns = ns;
        }
        self.start_ns = self.start_ns.min(ns);
        self.end_ns = self.end_ns.max(ns);
        *self.messages.entry(topic.to_string()).or_default() += 1;
    }

    fn total(&self) -> u64 {
        self.messages.values().sum()
    }
}

/// A ROS 2 message type's name and its message definition (`crate::ros::schema`).
pub type MessageType = (&'static str, fn() -> String);

/// The ROS 2 type of each recorded topic.
pub fn topic_type(topic: &str) -> Option<MessageType> {
    Some(match topic {
        topics::POINTS => (schema::POINT_CLOUD2, schema::point_cloud2),
        topics::JOINTS => (schema::JOINT_STATE, schema::joint_state),
        topics::DETECTIONS => (schema::DETECTION3D_ARRAY, schema::detection3d_array),
        topics::RANGE => (schema::IMAGE, schema::image),
        topics::MARKERS => (schema::MARKER_ARRAY, schema::marker_array),
        "/tf" | "/tf_static" => (schema::TF_MESSAGE, schema::tf_message),
        _ => return None,
    })
}

/// The QoS sqscand's ROS 2 node offers on `topic` at its defaults, as rosbag2 (Humble) writes
/// a topic's `offered_qos_profiles`: a YAML list of one profile, its policies as rmw's enum
/// numbers (history 1 keep last; reliability 1 reliable, 2 best effort; durability 1 transient
/// local, 2 volatile; liveliness 1 automatic) and "no limit" durations as Humble writes them.
pub fn offered_qos(topic: &str) -> String {
    let node = Ros2Config::default();
    let (reliable, transient_local, depth) = match topic {
        "/tf_static" => (true, true, 1),
        "/tf" => (true, false, topics::JOINT_STATES_PER_SWEEP),
        topics::JOINTS => (
            node.reliable,
            node.transient_local,
            node.depth.saturating_mul(topics::JOINT_STATES_PER_SWEEP),
        ),
        _ => (node.reliable, node.transient_local, node.depth),
    };
    let forever = "\n    sec: 2147483647\n    nsec: 4294967295";
    format!(
        "- history: 1\n  depth: {depth}\n  reliability: {}\n  durability: {}\n  deadline:{forever}\n  \
         lifespan:{forever}\n  liveliness: 1\n  liveliness_lease_duration:{forever}\n  \
         avoid_ros_namespace_conventions: false",
        if reliable { 1 } else { 2 },
        if transient_local { 1 } else { 2 },
    )
}

/// One rewrite at a time: two sweeps recorded at once each list the files and write the
/// metadata, and the later must list what the earlier wrote.
static WRITING: Mutex<()> = Mutex::new(());

/// Writes `dir/metadata.yaml` for the MCAP files the sweeps' JSON files in `dir` name; removes
/// it when there are none.
pub fn write_metadata(dir: &Path) -> Result<()> {
    let _one = WRITING.lock().unwrap_or_else(|p| p.into_inner());
    let mut files: Vec<(String, FileStats)> = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("cannot list {}", dir.display()))? {
        let Ok(e) = e else { continue };
        let name = e.file_name().to_string_lossy().into_owned();
        if !(name.starts_with("sweep-") && name.ends_with(".json")) {
            continue;
        }
        // A JSON being pruned, or not a recording's: not in the bag.
        let Ok(text) = std::fs::read_to_string(e.path()) else {
            continue;
        };
        let Ok(meta) = serde_json::from_str::<serde_json::Value>(&text) else {
            continue;
        };
        let (Some(mcap), Some(stats)) = (meta["mcap"].as_str(), meta.get("bag")) else {
            continue;
        };
        let Ok(stats) = serde_json::from_value::<FileStats>(stats.clone()) else {
            continue;
        };
        if dir.join(mcap).is_file() && stats.total() > 0 {
            files.push((mcap.to_string(), stats));
        }
    }
    let path = dir.join(METADATA);
    if files.is_empty() {
        return match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(e).with_context(|| format!("cannot remove {}", path.display()))
            }
            _ => Ok(()),
        };
    }
    // In time order: a reader plays the files one after the other.
    files.sort_by(|a, b| (a.1.start_ns, &a.0).cmp(&(b.1.start_ns, &b.0)));
    let text = metadata_yaml(&files);
    write_atomic(&path, |w| {
        use std::io::Write as _;
        w.write_all(text.as_bytes())?;
        Ok(())
    })
}

/// A YAML string scalar: JSON's quoting is YAML's double-quoted style.
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

fn metadata_yaml(files: &[(String, FileStats)]) -> String {
    use std::fmt::Write as _;
    let start = files.iter().map(|f| f.1.start_ns).min().unwrap_or(0);
    let end = files.iter().map(|f| f.1.end_ns).max().unwrap_or(0);
    let mut counts: BTreeMap<&str, u64> = BTreeMap::new();
    for (_, f) in files {
        for (topic, n) in &f.messages {
            *counts.entry(topic).or_default() += n;
        }
    }
    let total: u64 = counts.values().sum();
    let mut y = String::new();
    let _ = writeln!(y, "rosbag2_bagfile_information:");
    let _ = writeln!(y, "  version: {VERSION}");
    let _ = writeln!(y, "  storage_identifier: mcap");
    let _ = writeln!(y, "  duration:\n    nanoseconds: {}", end.saturating_sub(start));
    let _ = writeln!(y, "  starting_time:\n    nanoseconds_since_epoch: {start}");
    let _ = writeln!(y, "  message_count: {total}");
    let _ = writeln!(y, "  topics_with_message_count:");
    for (topic, n) in &counts {
        let Some((ty, _)) = topic_type(topic) else { continue };
        let _ = writeln!(y, "    - topic_metadata:");
        let _ = writeln!(y, "        name: {}", quoted(topic));
        let _ = writeln!(y, "        type: {}", quoted(ty));
        let _ = writeln!(y, "        serialization_format: cdr");
        let _ = writeln!(y, "        offered_qos_profiles: {}", quoted(&offered_qos(topic)));
        let _ = writeln!(y, "      message_count: {n}");
    }
    let _ = writeln!(y, "  compression_format: \"\"");
    let _ = writeln!(y, "  compression_mode: \"\"");
    let _ = writeln!(y, "  relative_file_paths:");
    for (name, _) in files {
        let _ = writeln!(y, "    - {}", quoted(name));
    }
    let _ = writeln!(y, "  files:");
    for (name, f) in files {
        let _ = writeln!(y, "    - path: {}", quoted(name));
        let _ = writeln!(
            y,
            "      starting_time:\n        nanoseconds_since_epoch: {}",
            f.start_ns
        );
        let _ = writeln!(y, "      duration:\n        nanoseconds: {}", f.end_ns - f.start_ns);
        let _ = writeln!(y, "      message_count: {}", f.total());
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_metadata_lists_the_files_in_time_order_and_counts_every_topic() {
        let mut a = FileStats::default();
        a.count("/tf_static", 2_000);
        a.count(topics::POINTS, 3_000);
        let mut b = FileStats::default();
        b.count(topics::POINTS, 1_000);
        b.count(topics::JOINTS, 500);
        let y = metadata_yaml(&[("sweep-00000002.mcap".into(), a), ("sweep-00000001.mcap".into(), b)]);
        assert!(y.contains("  version: 5\n  storage_identifier: mcap\n"), "{y}");
        assert!(y.contains("  duration:\n    nanoseconds: 2500\n"), "{y}");
        assert!(y.contains("nanoseconds_since_epoch: 500\n  message_count: 4\n"), "{y}");
        assert!(y.contains("name: \"/sqscan/points\"\n        type: \"sensor_msgs/msg/PointCloud2\""));
        assert!(y.contains("\"/sqscan/points\"\n        type: \"sensor_msgs/msg/PointCloud2\"\n        serialization_format: cdr\n        offered_qos_profiles: \"- history: 1\\n  depth: 5\\n  reliability: 1\\n  durability: 2\\n"), "{y}");
        assert!(y.contains("\"/tf_static\"\n        type: \"tf2_msgs/msg/TFMessage\"\n        serialization_format: cdr\n        offered_qos_profiles: \"- history: 1\\n  depth: 1\\n  reliability: 1\\n  durability: 1\\n"), "{y}");
        // As given: the caller sorts.
        assert!(y.find("- \"sweep-00000002.mcap\"") < y.find("- \"sweep-00000001.mcap\""));
    }
}
