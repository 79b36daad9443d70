//! `[ros2]`: the ROS 2 node's domain, names and QoS, validated as ROS 2 takes them.

use std::path::Path;

use serde::Deserialize;

use super::checks::{count_within, one_of};
use super::limits;
use crate::spec::SpecError;

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct Ros2File {
    /// The DDS domain, as `ROS_DOMAIN_ID` (default 0).
    domain_id: Option<u16>,
    /// The node's name (default `sqscand`) and namespace (default `/`).
    node: Option<String>,
    namespace: Option<String>,
    /// Topic names (defaults `/sqscan/points`, `/sqscan/joint_states`, `/sqscan/detections`,
    /// `/sqscan/markers`, `/sqscan/range`).
    points: Option<String>,
    joint_states: Option<String>,
    detections: Option<String>,
    markers: Option<String>,
    range: Option<String>,
    /// `"reliable"` (default) or `"best_effort"`.
    reliability: Option<String>,
    /// `"volatile"` (default) or `"transient_local"`.
    durability: Option<String>,
    /// Messages a topic keeps for a subscriber that is behind (keep-last depth, default 5).
    depth: Option<usize>,
    /// The largest sample reassembled from DDS fragments, KiB (default 1024).
    max_received_sample_kib: Option<usize>,
    /// Publish the PTU's joints on `/tf` at each profile (default true); false where the robot's
    /// own `robot_state_publisher` turns the joint states into transforms.
    publish_tf: Option<bool>,
}

/// The ROS 2 node (`[ros2]`, the `ros2` feature).
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Config {
    pub domain_id: u16,
    pub node: String,
    pub namespace: String,
    pub points: String,
    pub joint_states: String,
    pub detections: String,
    pub markers: String,
    pub range: String,
    pub reliable: bool,
    pub transient_local: bool,
    pub depth: usize,
    /// The largest sample RustDDS reassembles from fragments (bytes): a peer's DATA_FRAG that
    /// declares a larger one is dropped (`docs/ROS2.md`).
    pub max_received_sample: usize,
    /// The PTU's pan and tilt as transforms on `/tf` at each profile.
    pub publish_tf: bool,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Ros2Config {
            domain_id: 0,
            node: "sqscand".into(),
            namespace: "/".into(),
            points: "/sqscan/points".into(),
            joint_states: "/sqscan/joint_states".into(),
            detections: "/sqscan/detections".into(),
            markers: "/sqscan/markers".into(),
            range: "/sqscan/range".into(),
            reliable: true,
            transient_local: false,
            depth: 5,
            max_received_sample: 1 << 20,
            publish_tf: true,
        }
    }
}

/// Whether `name` is a ROS 2 name of `/`-separated tokens (letters, digits and single
/// underscores, not starting with a digit), absolute when it starts with `/`. `/` alone is the
/// root namespace.
fn ros_name(name: &str, namespace: bool) -> bool {
    if namespace && name == "/" {
        return true;
    }
    let body = name.strip_prefix('/').unwrap_or(name);
    if namespace && body.len() == name.len() {
        return false;
    }
    !body.is_empty()
        && !name.contains("__")
        && body.split('/').all(|t| {
            t.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
}

pub(super) fn ros2_config(path: &Path, r: &Ros2File) -> Result<Ros2Config, SpecError> {
    let mut c = Ros2Config::default();
    if let Some(d) = r.domain_id {
        // DDS maps a domain to UDP ports 7400 + 250 * domain and up: past 232 they leave the range.
        if d > limits::ROS_DOMAIN_ID {
            return Err(SpecError::invalid(
                path,
                "ros2.domain_id",
                format!("{d}: give a domain from 0 to {} (ROS_DOMAIN_ID)", limits::ROS_DOMAIN_ID),
            ));
        }
        c.domain_id = d;
    }
    if let Some(n) = &r.node {
        if n.contains('/') || !ros_name(n, false) {
            return Err(SpecError::invalid(
                path,
                "ros2.node",
                format!("{n:?}: give a node name like \"sqscand\" (letters, digits and _)"),
            ));
        }
        c.node = n.clone();
    }
    if let Some(n) = &r.namespace {
        if !ros_name(n, true) {
            return Err(SpecError::invalid(
                path,
                "ros2.namespace",
                format!("{n:?}: give an absolute namespace like \"/\" or \"/robot1\""),
            ));
        }
        c.namespace = n.clone();
    }
    for (key, given, to) in [
        ("ros2.points", &r.points, &mut c.points),
        ("ros2.joint_states", &r.joint_states, &mut c.joint_states),
        ("ros2.detections", &r.detections, &mut c.detections),
        ("ros2.markers", &r.markers, &mut c.markers),
        ("ros2.range", &r.range, &mut c.range),
    ] {
        if let Some(t) = given {
            if !ros_name(t, false) {
                return Err(SpecError::invalid(
                    path,
                    key,
                    format!(
                        "{t:?}: give a topic name like \"/sqscan/points\" (tokens of letters, digits and _ \
                         separated by /, none starting with a digit)"
                    ),
                ));
            }
            *to = t.clone();
        }
    }
    c.reliable = one_of(
        path,
        "ros2.reliability",
        r.reliability.as_deref(),
        &[("reliable", true), ("best_effort", false)],
    )?;
    c.transient_local = one_of(
        path,
        "ros2.durability",
        r.durability.as_deref(),
        &[("volatile", false), ("transient_local", true)],
    )?;
    if let Some(d) = count_within(path, "ros2.depth", r.depth, limits::ROS_DEPTH)? {
        c.depth = d;
    }
    if let Some(k) = r.max_received_sample_kib {
        let (lo, hi) = limits::ROS_MAX_RECEIVED_SAMPLE_KIB;
        if !(lo..=hi).contains(&k) {
            return Err(SpecError::invalid(
                path,
                "ros2.max_received_sample_kib",
                format!("{k}: give a size from {lo} to {hi} KiB"),
            ));
        }
        c.max_received_sample = k * 1024;
    }
    if let Some(b) = r.publish_tf {
        c.publish_tf = b;
    }
    if !cfg!(feature = "ros2") {
        return Err(SpecError::invalid(
            path,
            "ros2",
            "this sqscand was built without ROS 2 (cargo feature `ros2`)",
        ));
    }
    Ok(c)
}
