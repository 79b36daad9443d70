//! The ROS 2 topics sqscand publishes on (the live view, ROS 2) and records (MCAP), their
//! messages and the times they carry: one encoding for all. The ROS 2 node's topic names are
//! configurable (`[ros2]`); these are the defaults, and the names the others use.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use super::state::{Detected, DetectedEvent, Shared, SweepEntry};
use crate::model::Model;
use crate::ros::{self, Found, Header, Time};

/// The sweeps' clouds (`sensor_msgs/msg/PointCloud2`).
#[cfg_attr(not(any(feature = "mcap", feature = "foxglove")), allow(dead_code))]
pub const POINTS: &str = "/sqscan/points";
/// The PTU's joint angles at each profile (`sensor_msgs/msg/JointState`).
#[cfg_attr(not(any(feature = "mcap", feature = "foxglove")), allow(dead_code))]
pub const JOINTS: &str = "/sqscan/joint_states";
/// The detections (`vision_msgs/msg/Detection3DArray`).
#[cfg_attr(not(any(feature = "mcap", feature = "foxglove")), allow(dead_code))]
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

/// Each profile's `JointState` (pan and tilt), in time order, with its stamp.
pub fn joint_states(entry: &SweepEntry) -> impl Iterator<Item = (Time, Vec<u8>)> + '_ {
    let sweep = &entry.sweep;
    let last = last_profile_unix_s(entry);
    let last_stamp = sweep.stamp_s.last().copied().unwrap_or(0.0);
    sweep
        .pan_rad
        .iter()
        .zip(&sweep.tilt_rad)
        .enumerate()
        .map(move |(i, (pan, tilt))| {
            let stamp = Time::from_unix_s(last - (last_stamp - sweep.stamp_s.get(i).copied().unwrap_or(last_stamp)));
            let h = Header { stamp, frame_id: "" };
            (stamp, ros::joint_state(&h, &JOINT_NAMES, &[*pan, *tilt]))
        })
}

/// The sweep's `PointCloud2` in `frame`, stamped with the last profile's time.
pub fn cloud(entry: &SweepEntry, frame: &str) -> (Time, Vec<u8>) {
    let stamp = Time::from_unix_s(last_profile_unix_s(entry));
    (
        stamp,
        ros::point_cloud2(&entry.sweep.cloud, &Header { stamp, frame_id: frame }),
    )
}

/// One `Detection3DArray` of the objects found in `detections` on the sweep, at the sweep's time.
pub fn detections(entry: &SweepEntry, detections: &[(Arc<Model>, Arc<Detected>)], frame: &str) -> (Time, Vec<u8>) {
    let stamp = Time::from_unix_s(last_profile_unix_s(entry));
    let mut found: Vec<Found> = Vec::new();
    for (model, d) in detections {
        let bbox = ros::model_bbox(model);
        found.extend(d.report.detections.iter().filter(|x| x.found).map(|x| Found {
            object: &model.name,
            confidence: x.confidence,
            pose: x.pose,
            bbox,
        }));
    }
    (
        stamp,
        ros::detection3d_array(&Header { stamp, frame_id: frame }, &found),
    )
}

/// What a publisher of the daemon's topics (the live view, ROS 2) is handed.
pub enum Event {
    Sweep(Arc<SweepEntry>),
    Detection(DetectedEvent),
}

/// The daemon's sweeps and detections as they come, until it stops.
pub struct Follow {
    sweeps: tokio::sync::watch::Receiver<Option<Arc<SweepEntry>>>,
    detected: tokio::sync::broadcast::Receiver<DetectedEvent>,
    shutdown: tokio::sync::watch::Receiver<bool>,
    /// Who follows, for the warning when detections were skipped.
    who: &'static str,
}

impl Follow {
    pub fn new(shared: &Shared, who: &'static str) -> Follow {
        Follow {
            sweeps: shared.latest.subscribe(),
            detected: shared.detected.subscribe(),
            shutdown: shared.shutdown.subscribe(),
            who,
        }
    }

    /// The next sweep or detection; `None` once the daemon is stopping.
    pub async fn next(&mut self) -> Option<Event> {
        use tokio::sync::broadcast::error::RecvError;
        loop {
            tokio::select! {
                changed = self.sweeps.changed() => {
                    changed.ok()?;
                    if let Some(entry) = self.sweeps.borrow_and_update().clone() {
                        return Some(Event::Sweep(entry));
                    }
                }
                event = self.detected.recv() => match event {
                    Ok(event) => return Some(Event::Detection(event)),
                    Err(RecvError::Lagged(n)) => tracing::warn!("{} fell behind and skipped {n} detections", self.who),
                    Err(RecvError::Closed) => return None,
                },
                r = self.shutdown.changed() => {
                    if r.is_err() || *self.shutdown.borrow() {
                        return None;
                    }
                }
            }
        }
    }
}
