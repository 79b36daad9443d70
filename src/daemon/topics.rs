//! The ROS 2 topics sqscand publishes on (the live view) and records (MCAP), and the times
//! their messages carry.

use std::time::{Duration, SystemTime};

use super::state::SweepEntry;

/// The sweeps' clouds (`sensor_msgs/msg/PointCloud2`).
pub const POINTS: &str = "/sqscan/points";
/// The PTU's joint angles at each profile (`sensor_msgs/msg/JointState`).
pub const JOINTS: &str = "/sqscan/joint_states";
/// The detections (`vision_msgs/msg/Detection3DArray`).
pub const DETECTIONS: &str = "/sqscan/detections";
/// The joints' names in `JointState`.
pub const JOINT_NAMES: [&str; 2] = ["ptu_pan", "ptu_tilt"];

/// Unix time (s) of the sweep's last profile: its completion less the time from the last
/// profile's exposure to completion.
pub fn last_profile_unix_s(entry: &SweepEntry) -> f64 {
    let behind = entry.completed.saturating_duration_since(entry.last_profile);
    let t = entry.completed_wall.checked_sub(behind).unwrap_or(entry.completed_wall);
    t.duration_since(SystemTime::UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs_f64()
}

/// Unix time (s) of each profile's exposure, from the last one's and the sweep's stamps.
pub fn profile_unix_s(entry: &SweepEntry) -> impl Iterator<Item = f64> + '_ {
    let last = last_profile_unix_s(entry);
    let stamps = &entry.sweep.stamp_s;
    let last_stamp = stamps.last().copied().unwrap_or(0.0);
    (0..entry.sweep.pan_rad.len().min(entry.sweep.tilt_rad.len()))
        .map(move |i| last - (last_stamp - stamps.get(i).copied().unwrap_or(last_stamp)))
}
