//! The ROS 2 topics sqscand publishes on (the live view, ROS 2) and records (MCAP), their
//! messages and the times they carry: one encoding for all. The ROS 2 node's topic names are
//! configurable (`[ros2]`); these are the defaults, and the names the others use.

// Each of the three features publishes or records a different part of these.
#![cfg_attr(not(all(feature = "mcap", feature = "foxglove", feature = "ros2")), allow(dead_code))]

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use nalgebra::{Isometry3, Vector3};

use super::backend::{JointSample, Mount};
use super::state::{Detected, DetectedEvent, Shared, SweepEntry};
use crate::calibration;
use crate::model::Model;
use crate::ros::{self, Found, Header, Time, Transform};

/// The sweeps' clouds (`sensor_msgs/msg/PointCloud2`).
pub const POINTS: &str = "/sqscan/points";
/// The PTU's joint angles at each profile (`sensor_msgs/msg/JointState`).
pub const JOINTS: &str = "/sqscan/joint_states";
/// The detections (`vision_msgs/msg/Detection3DArray`).
pub const DETECTIONS: &str = "/sqscan/detections";
/// The sweeps' range images (`sensor_msgs/msg/Image`).
pub const RANGE: &str = "/sqscan/range";
/// The detections drawn (`visualization_msgs/msg/MarkerArray`).
pub const MARKERS: &str = "/sqscan/markers";
/// Joint states a sweep's worth of history holds: a PTU's samples (about 150 over a sweep at
/// 50 Hz) or a message a profile; kept for `depth` sweeps, as the other topics keep `depth`
/// messages.
pub const JOINT_STATES_PER_SWEEP: usize = 1000;
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

/// Each profile's time, pan and tilt (rad), in time order.
fn profiles(entry: &SweepEntry) -> impl Iterator<Item = (Time, f64, f64)> + '_ {
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
            (stamp, *pan, *tilt)
        })
}

/// The first profile's time.
pub fn first_profile_time(entry: &SweepEntry) -> Time {
    profiles(entry).next().map_or(Time::default(), |(t, _, _)| t)
}

/// Each profile's `JointState` (pan and tilt), in time order, with its stamp.
pub fn joint_states(entry: &SweepEntry) -> impl Iterator<Item = (Time, Vec<u8>)> + '_ {
    profiles(entry).map(|(stamp, pan, tilt)| (stamp, joint_state(stamp, pan, tilt)))
}

/// One `JointState`: the pan and tilt at `stamp`.
pub fn joint_state(stamp: Time, pan: f64, tilt: f64) -> Vec<u8> {
    let h = Header { stamp, frame_id: "" };
    ros::joint_state(&h, &JOINT_NAMES, &[pan, tilt])
}

/// The PTU frame (where the pan and tilt axes meet).
pub const PTU_FRAME: &str = "ptu_base_link";
/// The pan link: the PTU frame turned by the pan angle about its z axis.
pub const PAN_FRAME: &str = "ptu_pan_link";
/// The tilt link: the pan link turned by the tilt angle about its y axis.
pub const TILT_FRAME: &str = "ptu_tilt_link";
/// The sensor's frame.
pub const SENSOR_FRAME: &str = "sqscan_sensor";

/// The rig's two fixed transforms (`/tf_static`): the PTU in `frame`, the sensor on the tilt link.
pub fn tf_static(frame: &str, m: &Mount, stamp: Time) -> Vec<u8> {
    ros::tf_message(&[
        Transform {
            header: Header { stamp, frame_id: frame },
            child: PTU_FRAME,
            transform: m.ptu_in_base,
        },
        Transform {
            header: Header {
                stamp,
                frame_id: TILT_FRAME,
            },
            child: SENSOR_FRAME,
            transform: m.sensor_in_tilt,
        },
    ])
}

/// Each profile's joints as transforms (`/tf`): the pan link in the PTU frame, the tilt link
/// in the pan link, as the calibration chains them.
pub fn tf_joints(entry: &SweepEntry) -> impl Iterator<Item = (Time, Vec<u8>)> + '_ {
    profiles(entry).map(|(stamp, pan, tilt)| (stamp, tf_joint(stamp, pan, tilt)))
}

/// The joints at `stamp` as transforms (`/tf`).
pub fn tf_joint(stamp: Time, pan: f64, tilt: f64) -> Vec<u8> {
    ros::tf_message(&[
        Transform {
            header: Header {
                stamp,
                frame_id: PTU_FRAME,
            },
            child: PAN_FRAME,
            transform: calibration::pan_link(pan),
        },
        Transform {
            header: Header {
                stamp,
                frame_id: PAN_FRAME,
            },
            child: TILT_FRAME,
            transform: calibration::tilt_link(tilt),
        },
    ])
}

/// The sweep's range image (`sensor_msgs/Image`, `32FC1`): a row a profile, a column a sensor
/// column, the distance from the sensor (m), NaN for no return; in the sensor's frame, at the
/// last profile's time.
pub fn range_image(entry: &SweepEntry) -> (Time, Vec<u8>) {
    let stamp = Time::from_unix_s(last_profile_unix_s(entry));
    let s = &entry.sweep;
    let h = Header {
        stamp,
        frame_id: SENSOR_FRAME,
    };
    (stamp, ros::image_32fc1(&h, s.profiles, s.columns, &s.range_m))
}

/// Each part's colour in the markers: the first part red, the second blue, the third green.
const PART_COLORS: [ros::Rgba; 3] = [[0.9, 0.25, 0.2, 1.0], [0.2, 0.55, 0.95, 1.0], [0.3, 0.8, 0.3, 1.0]];

/// Spacing (m) of the points that draw a fitted part.
const PART_SPACING: f64 = 0.005;

/// Detections on one sweep as markers (`visualization_msgs/MarkerArray`): what was drawn before
/// is cleared, then every fitted part of each instance found is drawn as points on its surface,
/// a colour a part (namespace: the object), and the support plane as a thin square under the
/// first object found (namespace `plane`). Objects not found leave only the plane.
pub fn markers(entry: &SweepEntry, detections: &[(Arc<Model>, Arc<Detected>)], frame: &str) -> (Time, Vec<u8>) {
    use ros::{Marker, Shape};
    let stamp = Time::from_unix_s(last_profile_unix_s(entry));
    // Each object's name, and each instance found, its parts' surfaces.
    let surfaces: Vec<(&str, Vec<Vec<nalgebra::Point3<f64>>>)> = detections
        .iter()
        .flat_map(|(model, d)| {
            d.report.detections.iter().filter(|x| x.found).map(|x| {
                let parts = x
                    .parts
                    .iter()
                    .map(|p| {
                        p.placed
                            .as_ref()
                            .map_or_else(Vec::new, |q| q.sample_surface(PART_SPACING))
                    })
                    .collect();
                (model.name.as_str(), parts)
            })
        })
        .collect();
    let mut markers = vec![Marker {
        ns: "",
        id: 0,
        shape: Shape::DeleteAll,
        color: [0.0; 4],
    }];
    let mut instance: BTreeMap<&str, usize> = BTreeMap::new();
    for (name, parts) in &surfaces {
        let i = instance.entry(name).or_default();
        for (k, points) in parts.iter().enumerate().filter(|(_, p)| !p.is_empty()) {
            markers.push(Marker {
                ns: name,
                id: (16 * *i + k) as i32,
                shape: Shape::Points { points, size: 0.004 },
                color: PART_COLORS[k % PART_COLORS.len()],
            });
        }
        *i += 1;
    }
    let found = detections
        .iter()
        .flat_map(|(_, d)| d.report.detections.iter().filter(|x| x.found))
        .collect::<Vec<_>>();
    if let Some(plane) = detections.iter().find_map(|(_, d)| d.report.plane.as_ref()) {
        // Centred under the object found, else under the sensor's view of the sweep.
        let at = found
            .first()
            .map(|x| nalgebra::Point3::from(x.pose.translation.vector))
            .or(entry
                .sweep
                .cloud
                .viewpoint
                .map(|v| nalgebra::Point3::new(v[0], v[1], v[2])))
            .unwrap_or_else(nalgebra::Point3::origin);
        let on = at - plane.normal * plane.signed_distance(&at);
        let rotation = nalgebra::UnitQuaternion::rotation_between(&Vector3::z(), &plane.normal)
            .unwrap_or_else(|| nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        markers.push(Marker {
            ns: "plane",
            id: 0,
            shape: Shape::Cube {
                pose: Isometry3::from_parts(on.into(), rotation),
                size: Vector3::new(0.6, 0.6, 0.002),
            },
            color: [0.6, 0.6, 0.6, 0.35],
        });
    }
    (stamp, ros::marker_array(&Header { stamp, frame_id: frame }, &markers))
}

/// The sweep's `PointCloud2` in `frame`, stamped with the last profile's time.
pub fn cloud(entry: &SweepEntry, frame: &str) -> (Time, Vec<u8>) {
    let stamp = Time::from_unix_s(last_profile_unix_s(entry));
    (
        stamp,
        crate::cloud::point_cloud2(&entry.sweep.cloud, &Header { stamp, frame_id: frame }),
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
    /// The joint angles as a sweep goes (only to a follower that asked for them).
    Joints(JointSample),
}

/// The daemon's sweeps and detections as they come, until it stops.
pub struct Follow {
    sweeps: tokio::sync::watch::Receiver<Option<Arc<SweepEntry>>>,
    detected: tokio::sync::broadcast::Receiver<DetectedEvent>,
    joints: Option<tokio::sync::broadcast::Receiver<JointSample>>,
    shutdown: super::shutdown::Listener,
    /// Who follows, for the warning when detections were skipped.
    who: &'static str,
}

impl Follow {
    pub fn new(shared: &Shared, who: &'static str) -> Follow {
        Follow {
            sweeps: shared.sweeps(),
            detected: shared.detections(),
            joints: None,
            shutdown: shared.shutdown().listen(),
            who,
        }
    }

    /// Follows the joint angles too, as the backend reads them during each sweep.
    pub fn with_joints(mut self, shared: &Shared) -> Follow {
        self.joints = Some(shared.joints().subscribe());
        self
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
                Some(sample) = next_joint(&mut self.joints) => match sample {
                    Ok(sample) => return Some(Event::Joints(sample)),
                    Err(RecvError::Lagged(n)) => tracing::warn!("{} fell behind and skipped {n} joint samples", self.who),
                    Err(RecvError::Closed) => self.joints = None,
                },
                () = self.shutdown.thrown() => return None,
            }
        }
    }
}

/// The next joint sample of a follower that follows them; `None` (the branch disabled) for one
/// that does not.
async fn next_joint(
    joints: &mut Option<tokio::sync::broadcast::Receiver<JointSample>>,
) -> Option<Result<JointSample, tokio::sync::broadcast::error::RecvError>> {
    match joints {
        Some(rx) => Some(rx.recv().await),
        None => None,
    }
}

#[cfg(test)]
mod urdf_tests {
    use super::*;

    /// The shipped URDF (`dist/urdf/sqscan_ptu.urdf`) names the joints as the joint states do,
    /// chains the frames as `/tf` and `/tf_static` do, and turns each joint about the axis the
    /// calibration turns it about: what robot_state_publisher makes of it is what sqscand
    /// publishes itself.
    #[test]
    fn the_shipped_urdf_matches_the_published_joints_and_frames() {
        let urdf = include_str!("../../dist/urdf/sqscan_ptu.urdf");
        let joint = |name: &str| -> &str {
            let start = urdf
                .find(&format!("<joint name=\"{name}\""))
                .unwrap_or_else(|| panic!("no joint {name}"));
            let end = start + urdf[start..].find("</joint>").expect("a closed joint");
            &urdf[start..end]
        };
        let pan = joint(JOINT_NAMES[0]);
        let tilt = joint(JOINT_NAMES[1]);
        assert!(pan.contains(&format!("<parent link=\"{PTU_FRAME}\"/>")), "{pan}");
        assert!(pan.contains(&format!("<child link=\"{PAN_FRAME}\"/>")), "{pan}");
        assert!(tilt.contains(&format!("<parent link=\"{PAN_FRAME}\"/>")), "{tilt}");
        assert!(tilt.contains(&format!("<child link=\"{TILT_FRAME}\"/>")), "{tilt}");
        // The calibration's links: a pure turn about z (pan) and about y (tilt).
        let a = 0.7;
        let p = calibration::pan_link(a);
        let t = calibration::tilt_link(a);
        assert!(p.translation.vector.norm() < 1e-12 && t.translation.vector.norm() < 1e-12);
        assert!((p.rotation.axis().unwrap().into_inner() - nalgebra::Vector3::z()).norm() < 1e-12);
        assert!((t.rotation.axis().unwrap().into_inner() - nalgebra::Vector3::y()).norm() < 1e-12);
        assert!(pan.contains("<axis xyz=\"0 0 1\"/>") && pan.contains("<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>"));
        assert!(tilt.contains("<axis xyz=\"0 1 0\"/>") && tilt.contains("<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>"));
    }
}
